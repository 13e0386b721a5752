// Scene files: a strict reader. Every value is checked where it is read, so an error can name
// its JSON path; unknown keys are errors because a misspelt key silently ignored is a scene that
// quietly does something else.
#include "physics/scene_file.h"

#include "physics/generators.h"
#include "physics/mass.h"
#include "physics/mesh_loader.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <set>
#include <unordered_map>

namespace substep {

namespace {

// "12:5": a line and column rather than a JSON path (syntax errors).
bool isSourcePosition(const std::string& p) {
  if (p.empty() || p.find(':') == std::string::npos) return false;
  for (char ch : p)
    if (ch != ':' && (ch < '0' || ch > '9')) return false;
  return true;
}

std::string formatError(const std::string& file, const std::string& path, const std::string& message) {
  if (path.empty()) return file + ": " + message;
  if (isSourcePosition(path)) return file + ":" + path + ": " + message;
  return file + ": " + path + ": " + message;
}

}  // namespace

SceneError::SceneError(const std::string& file_, const std::string& path_, const std::string& message_)
    : std::runtime_error(formatError(file_, path_, message_)), file(file_), path(path_), message(message_) {}

namespace {

using json = nlohmann::json;

std::string join(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }
std::string item(const std::string& path, size_t i) { return path + "[" + std::to_string(i) + "]"; }

std::string inQuotes(const std::string& s) { return "\"" + s + "\""; }

std::string listOf(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

// What was found, for "got ...": the value for scalars, the type for containers.
std::string shown(const json& v) {
  if (v.is_number() || v.is_boolean() || v.is_null()) return v.dump();
  if (v.is_string()) {
    const std::string s = v.dump();
    return s.size() > 40 ? s.substr(0, 37) + "...\"" : s;
  }
  return v.is_array() ? "an array of " + std::to_string(v.size()) : "an object";
}

// A condition on a number, with the words that describe it in messages.
struct Cond {
  const char* text;  // "> 0"
  bool (*ok)(double);
};
const Cond kAny{"", [](double) { return true; }};
const Cond kPositive{"> 0", [](double x) { return x > 0; }};
const Cond kNonNegative{">= 0", [](double x) { return x >= 0; }};
const Cond kUnit{"in [0, 1]", [](double x) { return x >= 0 && x <= 1; }};
const Cond kDt{"in (0, 1]", [](double x) { return x > 0 && x <= 1; }};
const Cond kOmega{"in (0, 2)", [](double x) { return x > 0 && x < 2; }};
const Cond kPitch{"in [-90, 90]", [](double x) { return x >= -90 && x <= 90; }};
// Integers beyond this are typing errors, not requests (a generator of 1e9 bodies would just run out of memory).
constexpr int kMaxInt = 1000000;
const Cond kFov{"in (0, 180)", [](double x) { return x > 0 && x < 180; }};

class Reader;

// One JSON object being read: the checks every field needs, with its path at hand.
class Obj {
 public:
  Obj(const Reader& r, const json& j, std::string path);

  const std::string& path() const { return path_; }
  std::string at(const std::string& key) const { return join(path_, key); }
  [[noreturn]] void fail(const std::string& path, const std::string& message) const;

  void allow(const std::vector<std::string>& keys) const {
    for (auto it = j_.begin(); it != j_.end(); ++it)
      if (std::find(keys.begin(), keys.end(), it.key()) == keys.end())
        fail(path_, "unknown key " + inQuotes(it.key()) + " (expected one of: " + listOf(keys) + ")");
  }
  bool has(const std::string& k) const { return j_.contains(k); }
  const json& need(const std::string& k) const {
    if (!has(k)) fail(path_, "missing required field " + inQuotes(k));
    return j_.at(k);
  }

  double number(const std::string& k, const Cond& c) const { return toNumber(need(k), at(k), c); }
  double number(const std::string& k, const Cond& c, double def) const { return has(k) ? number(k, c) : def; }
  int integer(const std::string& k, int min, int max = kMaxInt) const { return toInt(need(k), at(k), min, max); }
  int integer(const std::string& k, int min, int max, int def) const { return has(k) ? integer(k, min, max) : def; }
  bool boolean(const std::string& k, bool def) const {
    if (!has(k)) return def;
    const json& v = j_.at(k);
    if (!v.is_boolean()) fail(at(k), "expected true or false, got " + typeName(v));
    return v.get<bool>();
  }
  std::string string(const std::string& k) const { return toString(need(k), at(k)); }
  std::string string(const std::string& k, const std::string& def) const { return has(k) ? string(k) : def; }
  Vec3 vec3(const std::string& k) const { return toVec3(need(k), at(k)); }
  Vec3 vec3(const std::string& k, const Vec3& def) const { return has(k) ? vec3(k) : def; }
  // A direction: non-zero, returned normalised.
  Vec3 unit(const std::string& k) const {
    const Vec3 v = vec3(k);
    if (!(v.norm() > 1e-9)) fail(at(k), "expected a non-zero vector, got " + shown(j_.at(k)));
    return v.normalized();
  }
  Vec3 unit(const std::string& k, const Vec3& def) const { return has(k) ? unit(k) : def; }

  // Typed conversions of any value (array elements too).
  static std::string typeName(const json& v) { return v.is_number() ? "number" : v.type_name(); }
  double toNumber(const json& v, const std::string& path, const Cond& c) const {
    const std::string expected = std::string("a number") + (c.text[0] ? " " : "") + c.text;
    if (!v.is_number()) fail(path, "expected " + expected + ", got " + typeName(v));
    const double x = v.get<double>();
    if (!std::isfinite(x)) fail(path, "expected a finite number, got " + v.dump());
    if (!c.ok(x)) fail(path, "expected " + expected + ", got " + shown(v));
    return x;
  }
  int toInt(const json& v, const std::string& path, int min, int max) const {
    const std::string range = max == kMaxInt ? ">= " + std::to_string(min)
                                             : "in [" + std::to_string(min) + ", " + std::to_string(max) + "]";
    const std::string expected = "an integer " + range;
    if (!v.is_number()) fail(path, "expected " + expected + ", got " + typeName(v));
    const double x = v.get<double>();
    if (!(x == std::floor(x)) || x < min || x > max) fail(path, "expected " + expected + ", got " + shown(v));
    return static_cast<int>(x);
  }
  std::string toString(const json& v, const std::string& path) const {
    if (!v.is_string()) fail(path, "expected a string, got " + typeName(v));
    return v.get<std::string>();
  }
  Vec3 toVec3(const json& v, const std::string& path) const {
    if (!v.is_array() || v.size() != 3) fail(path, "expected an array of 3 numbers [x, y, z], got " + shown(v));
    return Vec3(toNumber(v[0], item(path, 0), kAny), toNumber(v[1], item(path, 1), kAny),
                toNumber(v[2], item(path, 2), kAny));
  }

 private:
  const Reader& r_;
  const json& j_;
  std::string path_;
};

struct LoadedMesh {
  std::shared_ptr<const Mesh> mesh;
  Pose principal;  // convex meshes: the principal frame in the file's frame
};

class Reader {
 public:
  Reader(std::string file, std::string baseDir) : file_(std::move(file)), baseDir_(std::move(baseDir)) {}

  [[noreturn]] void fail(const std::string& path, const std::string& message) const {
    throw SceneError(file_, path.empty() ? "(top level)" : path, message);
  }

  Scene read(const json& root);

 private:
  void readSolver(const Obj& o, SolverOverrides& s) const;
  void readBody(const Obj& o, Scene& scene);
  Shape readShape(const Obj& o, bool isStatic, Pose* principal);
  void readMaterial(const Obj& o, BodyMaterial& m, bool isStatic) const;
  void readGenerator(const Obj& o, int index, Scene& scene);
  Quat quaternionAt(const Obj& o, const std::string& key) const;
  void readJoint(const Obj& o, int index, Scene& scene) const;
  CameraPreset readCamera(const Obj& o, const Scene& scene) const;
  LoadedMesh mesh(const Obj& o, bool convex, double scale);
  int bodyByName(const Obj& o, const json& v, const std::string& path, const Scene& scene) const;
  void claimName(const std::string& name, const std::string& path, const std::string& where);

  std::string file_, baseDir_;
  std::unordered_map<std::string, int> names_;   // body name -> index
  std::vector<std::string> definedAt_;           // body index -> JSON path that made it
  std::map<std::pair<std::string, double>, LoadedMesh> convexCache_, meshCache_;
};

Obj::Obj(const Reader& r, const json& j, std::string path) : r_(r), j_(j), path_(std::move(path)) {
  if (!j.is_object()) fail(path_, "expected an object, got " + typeName(j));
}

void Obj::fail(const std::string& path, const std::string& message) const { r_.fail(path, message); }

const std::vector<std::string> kShapeTypes = {"sphere", "box", "capsule", "cylinder", "convex", "plane", "mesh"};
const std::vector<std::string> kJointTypes = {"ball", "hinge", "cone_twist", "fixed", "spring", "motor"};
const std::vector<std::string> kGeneratorTypes = {"stack", "pyramid", "chain", "ragdoll"};

const json& arrayAt(const Obj& o, const std::string& k) {
  const json& v = o.need(k);
  if (!v.is_array()) o.fail(o.at(k), "expected an array, got " + Obj::typeName(v));
  return v;
}

std::string oneOf(const Obj& o, const std::string& k, const std::vector<std::string>& valid, const char* what) {
  const std::string s = o.string(k);
  if (std::find(valid.begin(), valid.end(), s) == valid.end())
    o.fail(o.at(k), std::string("unknown ") + what + " " + inQuotes(s) + " (expected one of: " + listOf(valid) + ")");
  return s;
}

Scene Reader::read(const json& root) {
  Obj top(*this, root, "");
  top.allow({"description", "gravity", "solver", "bodies", "joints", "generators", "cameras"});

  Scene scene;
  scene.file = file_;
  scene.model.name = std::filesystem::path(file_).stem().string();
  scene.description = top.string("description", "");
  scene.model.gravity = top.vec3("gravity", Vec3(0, -9.81, 0));
  if (top.has("solver")) readSolver(Obj(*this, top.need("solver"), "solver"), scene.solver);

  // Bodies, then generated bodies, then joints, which may name either.
  if (top.has("bodies")) {
    const json& a = arrayAt(top, "bodies");
    for (size_t i = 0; i < a.size(); ++i) readBody(Obj(*this, a[i], item("bodies", i)), scene);
  }
  if (top.has("generators")) {
    const json& a = arrayAt(top, "generators");
    for (size_t i = 0; i < a.size(); ++i)
      readGenerator(Obj(*this, a[i], item("generators", i)), static_cast<int>(i), scene);
  }
  if (top.has("joints")) {
    const json& a = arrayAt(top, "joints");
    for (size_t i = 0; i < a.size(); ++i) readJoint(Obj(*this, a[i], item("joints", i)), static_cast<int>(i), scene);
  }
  if (top.has("cameras")) {
    const json& a = arrayAt(top, "cameras");
    std::set<std::string> seen;
    for (size_t i = 0; i < a.size(); ++i) {
      const Obj o(*this, a[i], item("cameras", i));
      scene.cameras.push_back(readCamera(o, scene));
      if (!seen.insert(scene.cameras.back().name).second)
        fail(o.at("name"), "duplicate camera name " + inQuotes(scene.cameras.back().name));
    }
  }
  if (scene.model.dynamicCount() == 0)
    fail("", "expected at least one dynamic body, found none (" +
                 (scene.model.bodies.empty() ? std::string("no bodies at all")
                                             : std::to_string(scene.model.bodies.size()) + " static") + ")");
  return scene;
}

void Reader::readSolver(const Obj& o, SolverOverrides& s) const {
  o.allow({"algorithm", "dt", "substeps", "iterations", "omega", "tolerance", "kappa", "tau", "slop", "warm_start",
           "block_solve", "split_impulse", "preset"});
  if (o.has("algorithm")) {
    const std::string a = o.string("algorithm");
    s.algorithm = parseAlgorithm(a);
    if (!s.algorithm) fail(o.at("algorithm"), "expected one of a1, a2, a3, a4, a5, got " + inQuotes(a));
  }
  if (o.has("dt")) s.dt = o.number("dt", kDt);
  if (o.has("substeps")) s.substeps = o.integer("substeps", 1);
  if (o.has("iterations")) s.iterations = o.integer("iterations", 1);
  if (o.has("omega")) s.omega = o.number("omega", kOmega);
  if (o.has("tolerance")) s.tolerance = o.number("tolerance", kNonNegative);
  if (o.has("kappa")) s.kappa = o.number("kappa", kPositive);
  if (o.has("tau")) s.tau = o.number("tau", kNonNegative);
  if (o.has("slop")) s.slop = o.number("slop", kNonNegative);
  if (o.has("warm_start")) s.warmStart = o.boolean("warm_start", false);
  if (o.has("block_solve")) s.blockSolve = o.boolean("block_solve", false);
  if (o.has("split_impulse")) s.splitImpulse = o.boolean("split_impulse", false);
  if (o.has("preset")) s.preset = o.string("preset");
}

void Reader::claimName(const std::string& name, const std::string& path, const std::string& where) {
  if (name.empty()) fail(path, "expected a non-empty name");
  const auto it = names_.find(name);
  if (it != names_.end())
    fail(path, "duplicate body name " + inQuotes(name) + " (already used by " + definedAt_[it->second] + ")");
  names_[name] = static_cast<int>(definedAt_.size());
  definedAt_.push_back(where);
}

// Mass, density, friction, restitution and group, as bodies and generators give them.
void Reader::readMaterial(const Obj& o, BodyMaterial& m, bool isStatic) const {
  if (isStatic) {
    for (const char* k : {"mass", "density"})
      if (o.has(k)) fail(o.at(k), std::string("static bodies take no mass (remove \"") + k + "\" or make it dynamic)");
  }
  if (o.has("mass") && o.has("density")) fail(o.at("density"), "give either \"mass\" or \"density\", not both");
  if (o.has("mass")) m.mass = o.number("mass", kPositive);
  m.density = o.number("density", kPositive, 1000);
  m.friction = o.number("friction", kNonNegative, 0.5);
  m.restitution = o.number("restitution", kUnit, 0);
  m.group = o.integer("group", 0, kMaxInt, m.group);
}

LoadedMesh Reader::mesh(const Obj& o, bool convex, double scale) {
  namespace fs = std::filesystem;
  const std::string given = o.string("file");
  if (given.empty()) fail(o.at("file"), "expected a mesh file name, got \"\"");
  fs::path p(given);
  if (p.is_relative() && !baseDir_.empty()) p = fs::path(baseDir_) / p;
  const std::string path = p.lexically_normal().string();

  auto& cache = convex ? convexCache_ : meshCache_;
  const auto key = std::make_pair(path, scale);
  if (const auto it = cache.find(key); it != cache.end()) return it->second;

  Mesh m;
  try {
    m = loadMesh(path, scale);
  } catch (const SceneError& e) {
    fail(o.at("file"), "cannot load mesh " + inQuotes(path) + ": " + e.message);
  }
  LoadedMesh out;
  if (convex) {
    const double volume = meshVolume(m);
    if (!(volume > 0))
      fail(o.at("file"), "convex mesh " + inQuotes(path) + " has volume " + std::to_string(volume) +
                             " m^3; expected > 0 (a closed mesh, faces counter-clockwise seen from outside)");
    out.principal = toPrincipalFrame(m);
  }
  out.mesh = std::make_shared<const Mesh>(std::move(m));
  cache[key] = out;
  return out;
}

Shape Reader::readShape(const Obj& o, bool isStatic, Pose* principal) {
  const std::string type = oneOf(o, "type", kShapeTypes, "shape type");
  Shape s;
  if (type == "sphere") {
    o.allow({"type", "radius"});
    s.type = ShapeType::Sphere;
    s.radius = o.number("radius", kPositive);
  } else if (type == "box") {
    o.allow({"type", "half_extents"});
    s.type = ShapeType::Box;
    s.halfExtents = o.vec3("half_extents");
    for (int i = 0; i < 3; ++i)
      if (!(s.halfExtents[i] > 0))
        fail(item(o.at("half_extents"), i), "expected a number > 0, got " + o.need("half_extents")[i].dump());
  } else if (type == "capsule" || type == "cylinder") {
    o.allow({"type", "radius", "half_height"});
    s.type = type == "capsule" ? ShapeType::Capsule : ShapeType::Cylinder;
    s.radius = o.number("radius", kPositive);
    s.halfHeight = o.number("half_height", kPositive);
  } else if (type == "plane") {
    o.allow({"type", "normal", "offset"});
    s.type = ShapeType::Plane;
    s.normal = o.unit("normal", Vec3::UnitY());
    s.offset = o.number("offset", kAny, 0);
  } else {  // convex, mesh
    o.allow({"type", "file", "scale"});
    const bool convex = type == "convex";
    s.type = convex ? ShapeType::ConvexMesh : ShapeType::TriangleMesh;
    s.scale = o.number("scale", kPositive, 1);
    const LoadedMesh m = mesh(o, convex, s.scale);
    s.mesh = m.mesh;
    if (principal) *principal = m.principal;
  }
  if (!isStatic && (s.type == ShapeType::Plane || s.type == ShapeType::TriangleMesh))
    fail(o.at("type"), "a " + type + " has no volume: it can only be static (add \"static\": true)");
  return s;
}

void Reader::readBody(const Obj& o, Scene& scene) {
  o.allow({"name", "shape", "position", "orientation", "velocity", "angular_velocity", "mass", "density", "static",
           "friction", "restitution", "group"});
  Body b;
  b.name = o.string("name");
  claimName(b.name, o.at("name"), o.path());
  b.isStatic = o.boolean("static", false);
  if (b.isStatic)
    for (const char* k : {"velocity", "angular_velocity"})
      if (o.has(k)) fail(o.at(k), std::string("static bodies take no mass and do not move (remove \"") + k + "\")");

  BodyMaterial m;
  readMaterial(o, m, b.isStatic);
  b.friction = m.friction;
  b.restitution = m.restitution;
  b.group = m.group;

  Pose principal;  // identity but for convex meshes
  b.shape = readShape(Obj(*this, o.need("shape"), o.at("shape")), b.isStatic, &principal);

  Pose file;  // the pose the scene gives: of the shape's (mesh file's) frame
  file.p = o.vec3("position", Vec3::Zero());
  if (o.has("orientation")) file.q = quaternionAt(o, "orientation");

  try {
    if (m.mass)
      setMassFromMass(b, *m.mass);
    else
      setMassFromDensity(b, m.density);
  } catch (const std::invalid_argument& e) {
    fail(o.at("shape"), e.what());
  }

  BodyState s;
  s.x = file.apply(principal.p);
  s.q = (file.q * principal.q).normalized();
  s.v = o.vec3("velocity", Vec3::Zero());  // of the centre of mass
  s.w = s.q.conjugate() * o.vec3("angular_velocity", Vec3::Zero());  // files give it in the world frame
  addBody(scene, b, s);
}

// A unit quaternion [w, x, y, z] (normalised; zero is an error).
Quat Reader::quaternionAt(const Obj& o, const std::string& key) const {
  const json& v = o.need(key);
  const std::string path = o.at(key);
  if (!v.is_array() || v.size() != 4) fail(path, "expected a quaternion [w, x, y, z], got " + shown(v));
  const Quat q(o.toNumber(v[0], item(path, 0), kAny), o.toNumber(v[1], item(path, 1), kAny),
               o.toNumber(v[2], item(path, 2), kAny), o.toNumber(v[3], item(path, 3), kAny));
  if (!(q.norm() >= 1e-9)) fail(path, "expected a non-zero quaternion [w, x, y, z], got " + v.dump());
  return q.normalized();
}

void Reader::readGenerator(const Obj& o, int index, Scene& scene) {
  const std::string type = oneOf(o, "type", kGeneratorTypes, "generator type");
  std::vector<std::string> keys = {"type", "name", "mass", "density", "friction", "restitution", "group"};
  if (type == "stack") keys.insert(keys.end(), {"count", "half_extents", "position", "gap"});
  if (type == "pyramid") keys.insert(keys.end(), {"levels", "half_extents", "position", "gap"});
  if (type == "chain") keys.insert(keys.end(), {"count", "link", "anchor", "direction", "spacing", "joint"});
  if (type == "ragdoll")
    keys.insert(keys.end(), {"count", "columns", "position", "orientation", "offset", "spread", "yaw", "velocity", "scale"});
  o.allow(keys);

  BodyMaterial m;
  m.group = index;
  readMaterial(o, m, false);
  const std::string name = o.string("name", type + std::to_string(index));
  if (name.empty()) fail(o.at("name"), "expected a non-empty name");

  auto halfExtents = [&] {
    const Vec3 e = o.vec3("half_extents");
    for (int i = 0; i < 3; ++i)
      if (!(e[i] > 0)) fail(item(o.at("half_extents"), i), "expected a number > 0, got " + o.need("half_extents")[i].dump());
    return e;
  };

  const size_t first = scene.model.bodies.size();
  try {
    if (type == "stack") {
      StackParams p;
      p.count = o.integer("count", 1, 100000);
      p.halfExtents = halfExtents();
      p.position = o.vec3("position", Vec3::Zero());
      p.gap = o.number("gap", kNonNegative, 0);
      p.name = name;
      p.material = m;
      addStack(scene, p);
    } else if (type == "pyramid") {
      PyramidParams p;
      p.levels = o.integer("levels", 1, 400);  // 80200 boxes
      p.halfExtents = halfExtents();
      p.position = o.vec3("position", Vec3::Zero());
      p.gap = o.number("gap", kNonNegative, 0.01);
      p.name = name;
      p.material = m;
      addPyramid(scene, p);
    } else if (type == "ragdoll") {
      if (o.has("density")) fail(o.at("density"), "a ragdoll takes \"mass\" (of the whole ragdoll), not a density");
      RagdollParams p;
      p.count = o.integer("count", 1, 10000, 1);
      p.position = o.vec3("position", Vec3::Zero());
      if (o.has("orientation")) p.orientation = quaternionAt(o, "orientation");
      p.columns = o.integer("columns", 1, 10000, 1);
      p.offset = o.vec3("offset", Vec3(0, 1.2, 0));
      p.spread = o.vec3("spread", Vec3(0.8, 0, 0));
      p.yaw = o.number("yaw", kAny, 0);
      p.velocity = o.vec3("velocity", Vec3::Zero());
      p.scale = o.number("scale", kPositive, 1);
      if (m.mass) p.mass = *m.mass;
      p.name = name;
      p.material = m;
      p.material.mass.reset();
      addRagdoll(scene, p);
    } else {
      ChainParams p;
      p.count = o.integer("count", 1, 100000);
      const Obj link(*this, o.need("link"), o.at("link"));
      p.link = readShape(link, false, nullptr);
      if (p.link.type != ShapeType::Capsule && p.link.type != ShapeType::Box && p.link.type != ShapeType::Sphere)
        fail(link.at("type"), "expected a capsule, box or sphere link, got " + inQuotes(link.string("type")));
      p.anchor = o.vec3("anchor");
      p.direction = o.unit("direction", Vec3::UnitX());
      p.spacing = o.number("spacing", kPositive);
      const std::string joint = o.string("joint", "ball");
      if (joint == "ball")
        p.joint = JointType::Ball;
      else if (joint == "hinge")
        p.joint = JointType::Hinge;
      else
        fail(o.at("joint"), "expected \"ball\" or \"hinge\", got " + inQuotes(joint));
      p.name = name;
      p.material = m;
      addChain(scene, p);
    }
  } catch (const std::invalid_argument& e) {
    fail(o.path(), e.what());
  }

  const std::string namePath = o.has("name") ? o.at("name") : o.path();
  for (size_t i = first; i < scene.model.bodies.size(); ++i)
    claimName(scene.model.bodies[i].name, namePath, o.path() + " (" + scene.model.bodies[i].name + ")");
}

int Reader::bodyByName(const Obj& o, const json& v, const std::string& path, const Scene& scene) const {
  const std::string n = o.toString(v, path);
  const int i = scene.model.bodyIndex(n);
  if (i < 0) fail(path, "unknown body " + inQuotes(n));
  return i;
}

void Reader::readJoint(const Obj& o, int index, Scene& scene) const {
  const std::string t = oneOf(o, "type", kJointTypes, "joint type");
  JointType type = JointType::Ball;
  std::vector<std::string> keys = {"type", "name", "bodies", "collide"};
  if (t == "ball") {
    keys.insert(keys.end(), {"anchor"});
  } else if (t == "hinge") {
    type = JointType::Hinge;
    keys.insert(keys.end(), {"anchor", "axis", "limits", "motor"});
  } else if (t == "cone_twist") {
    type = JointType::ConeTwist;
    keys.insert(keys.end(), {"anchor", "axis", "limits", "swing"});
  } else if (t == "fixed") {
    type = JointType::Fixed;
    keys.insert(keys.end(), {"anchor"});
  } else if (t == "spring") {
    type = JointType::Spring;
    keys.insert(keys.end(), {"anchors", "rest_length"});
  } else {
    type = JointType::Motor;
    keys.insert(keys.end(), {"anchor", "axis", "motor"});
  }
  o.allow(keys);

  const json& bodies = o.need("bodies");
  const std::string bp = o.at("bodies");
  if (!bodies.is_array() || bodies.size() != 2) fail(bp, "expected two body names [A, B], got " + shown(bodies));
  const int a = bodyByName(o, bodies[0], item(bp, 0), scene);
  const int b = bodyByName(o, bodies[1], item(bp, 1), scene);
  if (a == b) fail(bp, "a joint needs two different bodies, got " + inQuotes(scene.model.bodies[a].name) + " twice");
  if (scene.model.bodies[a].isStatic && scene.model.bodies[b].isStatic)
    fail(bp, "both bodies are static; a joint needs at least one dynamic body");

  Vec3 anchorA, anchorB;
  if (type == JointType::Spring) {
    const json& v = o.need("anchors");
    const std::string ap = o.at("anchors");
    if (!v.is_array() || v.size() != 2) fail(ap, "expected two points [[x, y, z], [x, y, z]], got " + shown(v));
    anchorA = o.toVec3(v[0], item(ap, 0));
    anchorB = o.toVec3(v[1], item(ap, 1));
  } else {
    anchorA = anchorB = o.vec3("anchor");
  }
  const bool hasAxis = type == JointType::Hinge || type == JointType::ConeTwist || type == JointType::Motor;
  const Vec3 axis = hasAxis ? o.unit("axis") : Vec3::UnitX();  // the X axis still records the relative rotation

  Joint j = makeJoint(scene, type, a, b, anchorA, anchorB, axis);
  j.name = o.string("name", "joint" + std::to_string(index));
  j.collide = o.boolean("collide", false);
  if (o.has("limits")) {
    const json& v = o.need("limits");
    const std::string lp = o.at("limits");
    if (!v.is_array() || v.size() != 2) fail(lp, "expected [lower, upper] in radians, got " + shown(v));
    j.lower = o.toNumber(v[0], item(lp, 0), kAny);
    j.upper = o.toNumber(v[1], item(lp, 1), kAny);
    if (j.lower > j.upper) fail(lp, "expected lower <= upper, got " + v.dump());
    j.hasLimits = true;
  }
  if (type == JointType::ConeTwist) j.swing = o.number("swing", kPositive);
  if (type == JointType::Motor || o.has("motor")) {
    const Obj mo(*this, o.need("motor"), o.at("motor"));
    mo.allow({"speed", "max_torque"});
    j.hasMotor = true;
    j.motorSpeed = mo.number("speed", kAny);
    j.motorMaxTorque = mo.number("max_torque", kNonNegative, 0);
  }
  if (type == JointType::Spring) j.restLength = o.number("rest_length", kNonNegative, j.restLength);
  scene.model.joints.push_back(j);
}

CameraPreset Reader::readCamera(const Obj& o, const Scene& scene) const {
  o.allow({"name", "target", "yaw", "pitch", "distance", "fov", "follow"});
  CameraPreset c;
  c.name = o.string("name");
  if (c.name.empty()) fail(o.at("name"), "expected a non-empty name");
  c.target = o.vec3("target", c.target);
  c.yaw = o.number("yaw", kAny, c.yaw);
  c.pitch = o.number("pitch", kPitch, c.pitch);
  c.distance = o.number("distance", kPositive, c.distance);
  c.fovY = o.number("fov", kFov, c.fovY);
  if (o.has("follow")) {
    c.follow = o.string("follow");
    if (scene.model.bodyIndex(c.follow) < 0) fail(o.at("follow"), "unknown body " + inQuotes(c.follow));
  }
  return c;
}

// Duplicate keys: nlohmann keeps the last silently; we reject them like unknown keys. The parser
// callback sees keys as they arrive, so it tracks the path itself.
class DuplicateKeys {
 public:
  explicit DuplicateKeys(const std::string& file) : file_(file) {}

  bool operator()(int, json::parse_event_t ev, json& parsed) {
    using E = json::parse_event_t;
    switch (ev) {
      case E::object_start: stack_.push_back({false, 0, {}, {}}); break;
      case E::array_start: stack_.push_back({true, 0, {}, {}}); break;
      case E::key: {
        Frame& f = stack_.back();
        f.key = parsed.get<std::string>();
        if (!f.keys.insert(f.key).second) {
          const std::string p = path();
          throw SceneError(file_, p.empty() ? "(top level)" : p, "duplicate key " + inQuotes(f.key));
        }
        break;
      }
      case E::object_end:
      case E::array_end:
        stack_.pop_back();
        if (!stack_.empty() && stack_.back().array) ++stack_.back().index;
        break;
      case E::value:
        if (!stack_.empty() && stack_.back().array) ++stack_.back().index;
        break;
    }
    return true;
  }

 private:
  struct Frame {
    bool array;
    size_t index;
    std::string key;
    std::set<std::string> keys;
  };
  // Path of the innermost container (the one whose key repeats).
  std::string path() const {
    std::string p;
    for (size_t i = 0; i + 1 < stack_.size(); ++i)
      p = stack_[i].array ? item(p, stack_[i].index) : join(p, stack_[i].key);
    return p;
  }

  const std::string& file_;
  std::vector<Frame> stack_;
};

}  // namespace

Scene parseScene(const std::string& text, const std::string& file, const std::string& baseDir) {
  json root;
  try {
    root = json::parse(text, DuplicateKeys(file));
  } catch (const json::parse_error& e) {
    // nlohmann counts bytes from 1 and gives the last one read; turn it into line and column.
    const size_t pos = std::min(e.byte > 0 ? e.byte - 1 : 0, text.size());
    size_t line = 1, lineStart = 0;
    for (size_t i = 0; i < pos; ++i)
      if (text[i] == '\n') {
        ++line;
        lineStart = i + 1;
      }
    std::string what = e.what();
    // Drop nlohmann's "[json.exception.parse_error.101] parse error at line 1, column 2: ".
    if (const size_t k = what.find("parse error"); k != std::string::npos)
      if (const size_t colon = what.find(": ", k); colon != std::string::npos) what = what.substr(colon + 2);
    throw SceneError(file, std::to_string(line) + ":" + std::to_string(pos - lineStart + 1), "JSON syntax error: " + what);
  }
  return Reader(file, baseDir).read(root);
}

Scene loadScene(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw SceneError(path, "", std::string("cannot open: ") + std::strerror(EISDIR));
  FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw SceneError(path, "", std::string("cannot open: ") + std::strerror(errno));
  std::string text;
  char buf[1 << 16];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) text.append(buf, n);
  const bool failed = std::ferror(f);
  const int err = errno;
  std::fclose(f);
  if (failed) throw SceneError(path, "", std::string("cannot read: ") + std::strerror(err));

  const fs::path parent = fs::path(path).parent_path();
  return parseScene(text, path, parent.empty() ? "." : parent.string());
}

}  // namespace substep

// Scene files: a strict reader. Every value is checked where it is read, so an error can name
// its JSON path; unknown keys are errors because a misspelt key silently ignored is a scene that
// quietly does something else.
#include "physics/scene_file.h"
#include "physics/settings_json.h"
#include "physics/state_hash.h"

#include "physics/generators.h"
#include "physics/mass.h"
#include "physics/mesh_loader.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

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

// A name or value as a message quotes it: cut short, control characters escaped.
std::string inQuotes(const std::string& s) {
  std::string q = "\"";
  for (size_t i = 0; i < s.size(); ++i) {
    if (i == limits::kMaxMessageValue) {
      q += "...";
      break;
    }
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      q += buf;
    } else {
      q += s[i];
    }
  }
  return q + "\"";
}

std::string listOf(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

// What was found, for "got ...": the value for scalars, the type for containers.
std::string shown(const json& v) {
  if (v.is_number()) return numberText(v.get<double>());
  if (v.is_boolean() || v.is_null()) return v.dump();
  if (v.is_string()) return inQuotes(v.get<std::string>());
  return v.is_array() ? "an array of " + std::to_string(v.size()) : "an object";
}

// Ranges of numbers that are not physical quantities (those are in physics/limits.h).
constexpr Range kPitch{-90, 90};                      // camera [degrees]
constexpr Range kFov{0, 180, true, true};             // camera [degrees]
constexpr Range kQuatComponent{-1e6, 1e6};            // normalised after reading
constexpr Range kDirection{-1e6, 1e6};                // normalised after reading
constexpr Range kGroup{0, 1e6};
constexpr Range kInertia{1e-12, 1e12};                // principal moments [kg m^2]
constexpr Range kBits{0, 4294967295.0};               // a 32-bit category or mask

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

  double number(const std::string& k, const Range& c) const { return toNumber(need(k), at(k), c); }
  double number(const std::string& k, const Range& c, double def) const { return has(k) ? number(k, c) : def; }
  int integer(const std::string& k, int min, int max) const { return toInt(need(k), at(k), min, max); }
  int integer(const std::string& k, int min, int max, int def) const { return has(k) ? integer(k, min, max) : def; }
  bool boolean(const std::string& k, bool def) const {
    if (!has(k)) return def;
    const json& v = j_.at(k);
    if (!v.is_boolean()) fail(at(k), "expected true or false, got " + typeName(v));
    return v.get<bool>();
  }
  std::string string(const std::string& k) const { return toString(need(k), at(k)); }
  std::string string(const std::string& k, const std::string& def) const { return has(k) ? string(k) : def; }
  Vec3 vec3(const std::string& k, const Range& c) const { return toVec3(need(k), at(k), c); }
  Vec3 vec3(const std::string& k, const Range& c, const Vec3& def) const { return has(k) ? vec3(k, c) : def; }
  // A direction: non-zero, returned normalised.
  Vec3 unit(const std::string& k) const {
    const Vec3 v = vec3(k, kDirection);
    if (!(v.norm() > 1e-9)) fail(at(k), "expected a non-zero vector, got " + shown(j_.at(k)));
    return v.normalized();
  }
  Vec3 unit(const std::string& k, const Vec3& def) const { return has(k) ? unit(k) : def; }

  // Typed conversions of any value (array elements too).
  static std::string typeName(const json& v) { return v.is_number() ? "number" : v.type_name(); }
  double toNumber(const json& v, const std::string& path, const Range& c) const {
    if (!v.is_number()) fail(path, "expected " + c.expected() + ", got " + typeName(v));
    const double x = v.get<double>();
    if (!std::isfinite(x)) fail(path, "expected a finite number, got " + v.dump());
    if (!c.contains(x)) fail(path, "expected " + c.expected() + ", got " + shown(v));
    return x;
  }
  int toInt(const json& v, const std::string& path, int min, int max) const {
    const Range r{static_cast<double>(min), static_cast<double>(max)};
    if (!v.is_number()) fail(path, "expected " + r.expected(true) + ", got " + typeName(v));
    const double x = v.get<double>();
    if (!(x == std::floor(x)) || !r.contains(x)) fail(path, "expected " + r.expected(true) + ", got " + shown(v));
    return static_cast<int>(x);
  }
  std::string toString(const json& v, const std::string& path) const {
    if (!v.is_string()) fail(path, "expected a string, got " + typeName(v));
    return v.get<std::string>();
  }
  Vec3 toVec3(const json& v, const std::string& path, const Range& c) const {
    if (!v.is_array() || v.size() != 3) fail(path, "expected an array of 3 numbers [x, y, z], got " + shown(v));
    return Vec3(toNumber(v[0], item(path, 0), c), toNumber(v[1], item(path, 1), c), toNumber(v[2], item(path, 2), c));
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
  Reader(std::string file, std::string baseDir, const SceneLimits& lim)
      : file_(std::move(file)), baseDir_(std::move(baseDir)), maxBodies_(lim.maxBodies) {}

  [[noreturn]] void fail(const std::string& path, const std::string& message) const {
    throw SceneError(file_, path.empty() ? "(top level)" : path, message);
  }

  Scene read(const json& root);

 private:
  void readSolver(const Obj& o, SolverOverrides& s) const;
  void readCriteria(const Obj& o, Scene& scene) const;
  std::vector<int> bodyList(const Obj& o, const std::string& key, const Scene& scene) const;
  int dynamicBody(const Obj& o, const json& v, const std::string& path, const Scene& scene) const;
  void readBody(const Obj& o, Scene& scene);
  Shape readShape(const Obj& o, bool isStatic, Pose* principal);
  void readMaterial(const Obj& o, BodyMaterial& m, bool isStatic) const;
  uint32_t bits(const Obj& o, const std::string& key) const;
  void readGenerator(const Obj& o, int index, Scene& scene);
  Quat quaternionAt(const Obj& o, const std::string& key) const;
  void readJoint(const Obj& o, int index, Scene& scene) const;
  CameraPreset readCamera(const Obj& o, const Scene& scene) const;
  LoadedMesh mesh(const Obj& o, bool convex, double scale);
  int bodyByName(const Obj& o, const json& v, const std::string& path, const Scene& scene) const;
  void claimName(const std::string& name, const std::string& path, const std::string& where);
  void checkName(const std::string& name, const std::string& path) const;

  std::string file_, baseDir_;
  long long maxBodies_;
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
  top.allow({"description", "gravity", "solver", "bodies", "joints", "generators", "cameras", "criteria"});

  Scene scene;
  scene.file = file_;
  scene.model.name = std::filesystem::path(file_).stem().string();
  scene.description = top.string("description", "");
  scene.model.gravity = top.vec3("gravity", limits::kGravity, Vec3(0, -9.81, 0));
  if (top.has("solver")) readSolver(Obj(*this, top.need("solver"), "solver"), scene.solver);

  // Bodies, then generated bodies, then joints, which may name either.
  if (top.has("bodies")) {
    const json& a = arrayAt(top, "bodies");
    if (a.size() > static_cast<size_t>(maxBodies_))
      fail("bodies", "lists " + std::to_string(a.size()) + " bodies: more than the limit of " +
                         std::to_string(maxBodies_) + " (raise it with --max-bodies N)");
    for (size_t i = 0; i < a.size(); ++i) readBody(Obj(*this, a[i], item("bodies", i)), scene);
  }
  if (top.has("generators")) {
    const json& a = arrayAt(top, "generators");
    for (size_t i = 0; i < a.size(); ++i)
      readGenerator(Obj(*this, a[i], item("generators", i)), static_cast<int>(i), scene);
  }
  if (top.has("joints")) {
    const json& a = arrayAt(top, "joints");
    if (a.size() + scene.model.joints.size() > static_cast<size_t>(maxBodies_))
      fail("joints", "makes " + std::to_string(a.size() + scene.model.joints.size()) +
                         " joints: more than the limit of " + std::to_string(maxBodies_) +
                         " (raise it with --max-bodies N)");
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
  if (top.has("criteria")) readCriteria(Obj(*this, top.need("criteria"), "criteria"), scene);
  if (scene.model.dynamicCount() == 0)
    fail("", "expected at least one dynamic body, found none (" +
                 (scene.model.bodies.empty() ? std::string("no bodies at all")
                                             : std::to_string(scene.model.bodies.size()) + " static") + ")");
  return scene;
}

void Reader::readSolver(const Obj& o, SolverOverrides& s) const {
  std::vector<std::string> keys;
  for (const SettingSpec& spec : settingTable()) keys.push_back(spec.key);
  o.allow(keys);
  for (const SettingSpec& spec : settingTable()) {
    if (!o.has(spec.key)) continue;
    const json& v = o.need(spec.key);
    const std::string path = o.at(spec.key);
    try {
      switch (spec.kind) {
        case SettingKind::Integer:
        case SettingKind::Real:
          if (!v.is_number()) fail(path, "expected " + spec.expected() + ", got " + Obj::typeName(v));
          break;
        case SettingKind::Flag:
          if (!v.is_boolean()) fail(path, "expected true or false, got " + Obj::typeName(v));
          break;
        case SettingKind::Choice: o.toString(v, path); break;
      }
      s.set(spec, settingFromJson(spec, v));
    } catch (const std::invalid_argument& e) {
      fail(path, e.what());
    }
  }
}

// Ranges of the criteria's numbers.
constexpr Range kRunSeconds{0, 3600, true};   // a lab run [s]
constexpr Range kBound{0, 1e9};               // an "at most" of a criterion
constexpr Range kShare{0, 1, true};           // a fraction of the motion

int Reader::dynamicBody(const Obj& o, const json& v, const std::string& path, const Scene& scene) const {
  const int b = bodyByName(o, v, path, scene);
  if (scene.model.bodies[static_cast<size_t>(b)].isStatic)
    fail(path, "body " + inQuotes(scene.model.bodies[static_cast<size_t>(b)].name) + " is static; expected a dynamic body");
  return b;
}

std::vector<int> Reader::bodyList(const Obj& o, const std::string& key, const Scene& scene) const {
  // One name (a string) or a non-empty array of them, each a dynamic body, none twice.
  const json& v = o.need(key);
  const std::string path = o.at(key);
  if (v.is_string()) return {dynamicBody(o, v, path, scene)};
  if (!v.is_array() || v.empty()) fail(path, "expected a non-empty array of body names, got " + shown(v));
  std::vector<int> out;
  for (size_t i = 0; i < v.size(); ++i) {
    const int b = dynamicBody(o, v[i], item(path, i), scene);
    if (std::find(out.begin(), out.end(), b) != out.end()) fail(item(path, i), "body " + inQuotes(v[i].get<std::string>()) + " is listed twice");
    out.push_back(b);
  }
  return out;
}

void Reader::readCriteria(const Obj& o, Scene& scene) const {
  o.allow({"stresses", "seconds", "tolerance", "rest", "conservative", "error", "reference", "with", "pass"});
  SceneCriteria c;
  c.stresses = o.string("stresses", "");
  c.seconds = o.number("seconds", kRunSeconds, c.seconds);
  if (o.has("tolerance")) c.tolerance = o.number("tolerance", Range{0, limits::kLength.hi, true});
  if (o.has("rest")) c.rest = bodyList(o, "rest", scene);
  c.conservative = o.boolean("conservative", false);
  auto metricName = [&](const std::string& name, const std::string& path) {
    const auto& names = criterionMetrics();
    if (std::find(names.begin(), names.end(), name) == names.end())
      fail(path, "unknown quantity " + inQuotes(name) + " (expected one of: " + listOf(names) + ")");
  };
  if (o.has("error")) {
    c.error = o.string("error");
    metricName(c.error, o.at("error"));
  }
  if (o.has("reference")) {
    const Obj r(*this, o.need("reference"), o.at("reference"));
    const std::string type = oneOf(r, "type", {"pendulum", "free_fall", "torque_free", "converged"}, "reference type");
    SceneReference ref;
    if (type == "pendulum") {
      r.allow({"type", "body", "pivot"});
      ref.kind = SceneReference::Kind::Pendulum;
      const int b = dynamicBody(r, r.need("body"), r.at("body"), scene);
      ref.body = scene.model.bodies[static_cast<size_t>(b)].name;
      ref.pivot = r.vec3("pivot", limits::kCoordinate);
      if ((scene.initial.bodies[static_cast<size_t>(b)].x - ref.pivot).norm() < limits::kSize.lo)
        fail(r.at("pivot"), "the pivot is at the body's centre; a pendulum swings about a point away from it");
    } else if (type == "converged") {
      r.allow({"type", "method", "change"});
      ref.kind = SceneReference::Kind::Converged;
      ref.method = r.string("method");
      try {
        const std::vector<MethodSpec> m = expandMethodSpec(ref.method);
        if (m.size() != 1) fail(r.at("method"), "expected one method, got a grid of " + std::to_string(m.size()));
        if (!m[0].peer.empty()) fail(r.at("method"), "a reference is one of substep's algorithms (a1 or a3 at a small h), not the " + m[0].peer + " peer");
        if (!m[0].overrides.get(&SolverSettings::dt)) fail(r.at("method"), "give the reference's time step, e.g. \"a1:h=1/960\"");
      } catch (const std::invalid_argument& e) {
        fail(r.at("method"), e.what());
      }
      ref.change = r.number("change", kShare, ref.change);
    } else {
      r.allow({"type"});
      ref.kind = type == "free_fall" ? SceneReference::Kind::FreeFall : SceneReference::Kind::TorqueFree;
    }
    c.reference = ref;
  }
  // The two quantities a reference gives: named without one that gives them, they measure nothing
  // (every run "not measured").
  auto measuredAgainstReference = [&](const std::string& name, const std::string& path) {
    using K = SceneReference::Kind;
    const std::optional<K> kind = c.reference ? std::optional<K>(c.reference->kind) : std::nullopt;
    if (name == "trajectory_error" && (!kind || kind == K::TorqueFree))
      fail(path, std::string("trajectory_error is the distance from a reference trajectory, and ") +
                     (kind ? "a torque_free reference gives none" : "the criteria state no reference") +
                     "; give criteria.reference (pendulum, free_fall or converged, e.g. {\"type\": \"converged\", \"method\": \"a1:h=1/960\"})");
    if (name == "reference_error" && kind != K::Pendulum && kind != K::TorqueFree)
      fail(path, std::string("reference_error is the error against a closed form, and ") +
                     (kind ? "a free_fall or converged reference gives none (its error is trajectory_error)" : "the criteria state no reference") +
                     "; give criteria.reference of type pendulum or torque_free");
  };
  if (!c.error.empty()) measuredAgainstReference(c.error, o.at("error"));
  if (o.has("with")) {
    const Obj w(*this, o.need("with"), o.at("with"));
    readSolver(w, c.with);
    if (c.with.algorithm() || c.with.preset())
      fail(w.path(), "\"with\" holds settings every method runs with; the algorithm and presets are the method's");
  }
  if (o.has("pass")) {
    const Obj p(*this, o.need("pass"), o.at("pass"));
    std::vector<std::string> keys = criterionMetrics();
    keys.insert(keys.end(), {"moving", "stay_in", "turns"});
    p.allow(keys);
    for (const std::string& name : criterionMetrics())
      if (p.has(name)) {
        measuredAgainstReference(name, p.at(name));
        c.pass.emplace_back(name, p.number(name, kBound));
      }
    if (p.has("moving")) {
      const Obj m(*this, p.need("moving"), p.at("moving"));
      m.allow({"bodies", "at_least"});
      c.moving = SceneCriteria::Moving{bodyList(m, "bodies", scene), m.number("at_least", Range{0, limits::kLength.hi, true})};
    }
    if (p.has("stay_in")) {
      const Obj m(*this, p.need("stay_in"), p.at("stay_in"));
      m.allow({"body", "min", "max"});
      SceneCriteria::StayIn in;
      in.body = bodyList(m, "body", scene)[0];
      in.lo = m.vec3("min", limits::kCoordinate);
      in.hi = m.vec3("max", limits::kCoordinate);
      const Vec3 x = scene.initial.bodies[static_cast<size_t>(in.body)].x;
      for (int k = 0; k < 3; ++k) {
        if (!(in.lo[k] < in.hi[k])) fail(m.path(), "expected min < max on every axis; axis " + std::string(1, "xyz"[k]) + " has " + numberText(in.lo[k]) + " and " + numberText(in.hi[k]));
        if (x[k] < in.lo[k] || x[k] > in.hi[k]) fail(m.path(), "body " + inQuotes(scene.model.bodies[static_cast<size_t>(in.body)].name) + " starts outside the box (axis " + std::string(1, "xyz"[k]) + ")");
      }
      c.stayIn = in;
    }
    if (p.has("turns")) {
      const Obj m(*this, p.need("turns"), p.at("turns"));
      m.allow({"body", "axis", "at_least"});
      SceneCriteria::Turns t;
      t.body = bodyList(m, "body", scene)[0];
      t.axis = m.unit("axis");
      t.atLeast = m.number("at_least", Range{0, 3.1416, true});
      c.turns = t;
    }
  }
  scene.criteria = c;
}

// Names end up in CSV columns, messages and the HUD: printable, and not a paragraph.
void Reader::checkName(const std::string& name, const std::string& path) const {
  if (name.empty()) fail(path, "expected a non-empty name");
  if (name.size() > limits::kMaxNameLength)
    fail(path, "a name of " + std::to_string(name.size()) + " bytes; expected at most " +
                   std::to_string(limits::kMaxNameLength));
  for (const char c : name)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
      fail(path, "the name " + inQuotes(name) + " holds a control character; expected printable text");
}

void Reader::claimName(const std::string& name, const std::string& path, const std::string& where) {
  checkName(name, path);
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
  if (o.has("mass")) m.mass = o.number("mass", limits::kMass);
  m.density = o.number("density", limits::kDensity, 1000);
  m.friction = o.number("friction", limits::kFriction, 0.5);
  m.restitution = o.number("restitution", limits::kRestitution, 0);
  m.group = o.integer("group", 0, static_cast<int>(kGroup.hi), m.group);
  // Collision filtering (model.h): Box2D's category and mask bits, and a filter group.
  if (o.has("category")) m.category = bits(o, "category");
  if (o.has("mask")) m.mask = bits(o, "mask");
  m.filterGroup = o.integer("filter_group", -1000000, 1000000, m.filterGroup);
}

uint32_t Reader::bits(const Obj& o, const std::string& key) const {
  const double x = o.number(key, kBits);
  if (x != std::floor(x)) fail(o.at(key), "expected an integer in [0, 4294967295] (a bit mask), got " + numberText(x));
  return static_cast<uint32_t>(x);
}

LoadedMesh Reader::mesh(const Obj& o, bool convex, double scale) {
  namespace fs = std::filesystem;
  const std::string given = o.string("file");
  if (given.empty()) fail(o.at("file"), "expected a mesh file name, got \"\"");
  // Before any path arithmetic: "a.obj\0b.obj" would otherwise open a.obj, or lose its NUL in
  // normalisation and open another file.
  if (given.find('\0') != std::string::npos)
    fail(o.at("file"), "the file name " + inQuotes(given) + " holds a NUL character");
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
  // The mesh's size after scaling, as any shape's (limits.h).
  Vec3 lo = m.vertices[0], hi = m.vertices[0];
  for (const Vec3& v : m.vertices) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
  const double half = 0.5 * (hi - lo).maxCoeff();
  if (!limits::kSize.contains(half))
    fail(o.at(o.has("scale") ? "scale" : "file"), "mesh " + inQuotes(path) + " is " + numberText(2 * half) +
                                                      " m across after scaling; expected a half size " +
                                                      limits::kSize.text() + " m");
  LoadedMesh out;
  if (convex) {
    if (const std::string why = closedSurfaceProblem(m); !why.empty())
      fail(o.at("file"), "convex mesh " + inQuotes(path) + ": " + why);
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
    s.radius = o.number("radius", limits::kSize);
  } else if (type == "box") {
    o.allow({"type", "half_extents"});
    s.type = ShapeType::Box;
    s.halfExtents = o.vec3("half_extents", limits::kSize);
  } else if (type == "capsule" || type == "cylinder") {
    o.allow({"type", "radius", "half_height"});
    s.type = type == "capsule" ? ShapeType::Capsule : ShapeType::Cylinder;
    s.radius = o.number("radius", limits::kSize);
    s.halfHeight = o.number("half_height", limits::kSize);
  } else if (type == "plane") {
    o.allow({"type", "normal", "offset"});
    s.type = ShapeType::Plane;
    s.normal = o.unit("normal", Vec3::UnitY());
    s.offset = o.number("offset", limits::kCoordinate, 0);
  } else {  // convex, mesh
    o.allow({"type", "file", "scale"});
    const bool convex = type == "convex";
    s.type = convex ? ShapeType::ConvexMesh : ShapeType::TriangleMesh;
    s.scale = o.number("scale", limits::kScale, 1);
    const LoadedMesh m = mesh(o, convex, s.scale);
    s.mesh = m.mesh;
    if (principal) *principal = m.principal;
  }
  if (!isStatic && (s.type == ShapeType::Plane || s.type == ShapeType::TriangleMesh))
    fail(o.at("type"), "a " + type + " has no volume: it can only be static (add \"static\": true)");
  return s;
}

void Reader::readBody(const Obj& o, Scene& scene) {
  o.allow({"name", "shape", "position", "orientation", "velocity", "angular_velocity", "mass", "density", "inertia",
           "static", "friction", "restitution", "group", "category", "mask", "filter_group"});
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
  b.category = m.category;
  b.mask = m.mask;
  b.filterGroup = m.filterGroup;

  Pose principal;  // identity but for convex meshes
  b.shape = readShape(Obj(*this, o.need("shape"), o.at("shape")), b.isStatic, &principal);

  Pose file;  // the pose the scene gives: of the shape's (mesh file's) frame
  file.p = o.vec3("position", limits::kCoordinate, Vec3::Zero());
  if (o.has("orientation")) file.q = quaternionAt(o, "orientation");

  try {
    if (m.mass)
      setMassFromMass(b, *m.mass);
    else
      setMassFromDensity(b, m.density);
  } catch (const std::invalid_argument& e) {
    fail(o.at("shape"), e.what());
  }
  if (o.has("inertia")) {
    // Principal moments along the shape's own axes, for a scene that models a reference which
    // states them (a physical pendulum); the mass must be given too.
    if (b.isStatic) fail(o.at("inertia"), "static bodies take no inertia (remove \"inertia\")");
    if (!m.mass) fail(o.at("inertia"), "give the body's \"mass\" with its inertia");
    const Vec3 I = o.vec3("inertia", kInertia);
    for (int k = 0; k < 3; ++k) {  // the triangle inequality of principal moments
      const double other = I[(k + 1) % 3] + I[(k + 2) % 3];
      if (I[k] > other * (1 + 1e-9))
        fail(o.at("inertia"), "principal moments " + numberText(I.x()) + ", " + numberText(I.y()) + ", " +
                                  numberText(I.z()) + " are no rigid body's: each must be at most the sum of the other two");
    }
    b.inertia = I;
    b.invInertia = I.cwiseInverse();
  }
  if (!b.isStatic && !limits::kMass.contains(b.mass))
    fail(o.has("density") ? o.at("density") : o.at("shape"),
         "this shape at this density weighs " + numberText(b.mass) + " kg; expected a body mass " +
             limits::kMass.text() + " kg (give \"mass\" or another \"density\")");

  BodyState s;
  s.x = file.apply(principal.p);
  s.q = (file.q * principal.q).normalized();
  s.v = o.vec3("velocity", limits::kSpeed, Vec3::Zero());  // of the centre of mass
  // Files give it in the world frame.
  s.w = s.q.conjugate() * o.vec3("angular_velocity", limits::kAngularSpeed, Vec3::Zero());
  addBody(scene, b, s);
}

// A unit quaternion [w, x, y, z] (normalised; zero is an error).
Quat Reader::quaternionAt(const Obj& o, const std::string& key) const {
  const json& v = o.need(key);
  const std::string path = o.at(key);
  if (!v.is_array() || v.size() != 4) fail(path, "expected a quaternion [w, x, y, z], got " + shown(v));
  const Quat q(o.toNumber(v[0], item(path, 0), kQuatComponent), o.toNumber(v[1], item(path, 1), kQuatComponent),
               o.toNumber(v[2], item(path, 2), kQuatComponent), o.toNumber(v[3], item(path, 3), kQuatComponent));
  if (!(q.norm() >= 1e-9)) fail(path, "expected a non-zero quaternion [w, x, y, z], got " + v.dump());
  return q.normalized();
}

void Reader::readGenerator(const Obj& o, int index, Scene& scene) {
  const std::string type = oneOf(o, "type", kGeneratorTypes, "generator type");
  std::vector<std::string> keys = {"type",  "name", "mass",     "density",     "friction",
                                   "restitution", "group", "category", "mask", "filter_group"};
  if (type == "stack") keys.insert(keys.end(), {"count", "half_extents", "position", "gap"});
  if (type == "pyramid") keys.insert(keys.end(), {"levels", "half_extents", "position", "gap"});
  if (type == "chain")
    keys.insert(keys.end(), {"count", "link", "anchor", "direction", "spacing", "joint", "anchor_radius", "self_collision"});
  if (type == "ragdoll")
    keys.insert(keys.end(),
                {"count", "columns", "position", "orientation", "offset", "spread", "yaw", "velocity", "scale", "self_collision"});
  o.allow(keys);

  BodyMaterial m;
  m.group = index;
  readMaterial(o, m, false);
  // Without self-collision the bodies of a chain (or each ragdoll) never touch each other; with
  // it (the default) only jointed neighbours do not, unless their joint says they may.
  if (!o.boolean("self_collision", true)) {
    if (o.has("filter_group")) fail(o.at("self_collision"), "give either \"self_collision\" or \"filter_group\"");
    m.filterGroup = -(index + 1);
  }
  const std::string name = o.string("name", type + std::to_string(index));
  checkName(name, o.has("name") ? o.at("name") : o.path());
  auto halfExtents = [&] { return o.vec3("half_extents", limits::kSize); };
  // Bodies this generator would add, checked against the cap before any is made.
  auto room = [&](const std::string& key, long long adding, const std::string& what) {
    const long long total = static_cast<long long>(scene.model.bodies.size()) + adding;
    if (total > maxBodies_)
      fail(o.at(key), what + " make " + std::to_string(adding) + " bodies, " + std::to_string(total) +
                          " with those before: more than the limit of " + std::to_string(maxBodies_) +
                          " bodies (raise it with --max-bodies N)");
  };

  const size_t first = scene.model.bodies.size();
  try {
    if (type == "stack") {
      StackParams p;
      p.count = o.integer("count", 1, limits::kMaxBodiesCeiling);
      room("count", p.count, std::to_string(p.count) + " boxes");
      p.halfExtents = halfExtents();
      p.position = o.vec3("position", limits::kCoordinate, Vec3::Zero());
      p.gap = o.number("gap", limits::kLength, 0);
      p.name = name;
      p.material = m;
      addStack(scene, p);
    } else if (type == "pyramid") {
      PyramidParams p;
      p.levels = o.integer("levels", 1, 1500);  // 1.1 million boxes
      room("levels", static_cast<long long>(p.levels) * (p.levels + 1) / 2, std::to_string(p.levels) + " levels");
      p.halfExtents = halfExtents();
      p.position = o.vec3("position", limits::kCoordinate, Vec3::Zero());
      p.gap = o.number("gap", limits::kLength, 0.01);
      p.name = name;
      p.material = m;
      addPyramid(scene, p);
    } else if (type == "ragdoll") {
      if (o.has("density")) fail(o.at("density"), "a ragdoll takes \"mass\" (of the whole ragdoll), not a density");
      RagdollParams p;
      p.count = o.integer("count", 1, limits::kMaxBodiesCeiling, 1);
      room(o.has("count") ? "count" : "type", 15LL * p.count, std::to_string(p.count) + " ragdolls of 15 bodies");
      p.position = o.vec3("position", limits::kCoordinate, Vec3::Zero());
      if (o.has("orientation")) p.orientation = quaternionAt(o, "orientation");
      p.columns = o.integer("columns", 1, limits::kMaxBodiesCeiling, 1);
      p.offset = o.vec3("offset", limits::kCoordinate, Vec3(0, 1.2, 0));
      p.spread = o.vec3("spread", limits::kCoordinate, Vec3(0.8, 0, 0));
      p.yaw = o.number("yaw", limits::kJointAngle, 0);
      p.velocity = o.vec3("velocity", limits::kSpeed, Vec3::Zero());
      p.scale = o.number("scale", limits::kScale, 1);
      if (m.mass) p.mass = *m.mass;
      p.name = name;
      p.material = m;
      p.material.mass.reset();
      addRagdoll(scene, p);
    } else {
      ChainParams p;
      p.count = o.integer("count", 1, limits::kMaxBodiesCeiling);
      room("count", p.count + 1LL, std::to_string(p.count) + " links and their anchor");
      const Obj link(*this, o.need("link"), o.at("link"));
      p.link = readShape(link, false, nullptr);
      if (p.link.type != ShapeType::Capsule && p.link.type != ShapeType::Box && p.link.type != ShapeType::Sphere)
        fail(link.at("type"), "expected a capsule, box or sphere link, got " + inQuotes(link.string("type")));
      p.anchor = o.vec3("anchor", limits::kCoordinate);
      p.direction = o.unit("direction", Vec3::UnitX());
      p.spacing = o.number("spacing", limits::kSize);
      p.anchorRadius = o.number("anchor_radius", limits::kSize, p.anchorRadius);
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
  for (size_t i = first; i < scene.model.bodies.size(); ++i) {
    const Body& b = scene.model.bodies[i];
    claimName(b.name, namePath, o.path() + " (" + b.name + ")");
    // Each parameter was in range; what they make together must be too (a stack of a thousand
    // 100 m boxes reaches beyond the coordinate range).
    const Vec3& x = scene.initial.bodies[i].x;
    for (int k = 0; k < 3; ++k)
      if (!limits::kCoordinate.contains(x[k]))
        fail(o.path(), "generated body " + inQuotes(b.name) + " lies at " + numberText(x[k]) + " m on axis " +
                           "xyz"[k] + "; expected every coordinate " + limits::kCoordinate.text() + " m");
    if (!b.isStatic && !limits::kMass.contains(b.mass))
      fail(o.path(), "generated body " + inQuotes(b.name) + " weighs " + numberText(b.mass) + " kg; expected a mass " +
                         limits::kMass.text() + " kg");
  }
  if (scene.model.joints.size() > static_cast<size_t>(maxBodies_))
    fail(o.path(), "makes " + std::to_string(scene.model.joints.size()) + " joints: more than the limit of " +
                       std::to_string(maxBodies_) + " (raise it with --max-bodies N)");
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
    anchorA = o.toVec3(v[0], item(ap, 0), limits::kCoordinate);
    anchorB = o.toVec3(v[1], item(ap, 1), limits::kCoordinate);
  } else {
    anchorA = anchorB = o.vec3("anchor", limits::kCoordinate);
  }
  const bool hasAxis = type == JointType::Hinge || type == JointType::ConeTwist || type == JointType::Motor;
  const Vec3 axis = hasAxis ? o.unit("axis") : Vec3::UnitX();  // the X axis still records the relative rotation

  Joint j = makeJoint(scene, type, a, b, anchorA, anchorB, axis);
  j.name = o.string("name", "joint" + std::to_string(index));
  if (o.has("name")) checkName(j.name, o.at("name"));
  j.collide = o.boolean("collide", false);
  if (o.has("limits")) {
    const json& v = o.need("limits");
    const std::string lp = o.at("limits");
    if (!v.is_array() || v.size() != 2) fail(lp, "expected [lower, upper] in radians, got " + shown(v));
    j.lower = o.toNumber(v[0], item(lp, 0), limits::kJointAngle);
    j.upper = o.toNumber(v[1], item(lp, 1), limits::kJointAngle);
    if (j.lower > j.upper) fail(lp, "expected lower <= upper, got " + v.dump());
    j.hasLimits = true;
  }
  if (type == JointType::ConeTwist) j.swing = o.number("swing", limits::kSwing);
  if (type == JointType::Motor || o.has("motor")) {
    const Obj mo(*this, o.need("motor"), o.at("motor"));
    mo.allow({"speed", "max_torque"});
    j.hasMotor = true;
    j.motorSpeed = mo.number("speed", limits::kMotorSpeed);
    j.motorMaxTorque = mo.number("max_torque", limits::kTorque, 0);
  }
  if (type == JointType::Spring) j.restLength = o.number("rest_length", limits::kLength, j.restLength);
  scene.model.joints.push_back(j);
}

CameraPreset Reader::readCamera(const Obj& o, const Scene& scene) const {
  o.allow({"name", "target", "yaw", "pitch", "distance", "fov", "follow"});
  CameraPreset c;
  c.name = o.string("name");
  checkName(c.name, o.at("name"));
  c.target = o.vec3("target", limits::kCoordinate, c.target);
  c.yaw = o.number("yaw", limits::kDegrees, c.yaw);
  c.pitch = o.number("pitch", kPitch, c.pitch);
  c.distance = o.number("distance", limits::kDistance, c.distance);
  c.fovY = o.number("fov", kFov, c.fovY);
  if (o.has("follow")) {
    c.follow = o.string("follow");
    if (scene.model.bodyIndex(c.follow) < 0) fail(o.at("follow"), "unknown body " + inQuotes(c.follow));
  }
  return c;
}

// A first pass over the text with nlohmann's SAX interface, before the DOM is built: it refuses
// what the DOM would accept silently (duplicate keys: nlohmann keeps the last) or at a cost
// (500 000 nested arrays), and it keeps the position of every syntax error, which the DOM parser's
// exceptions for numbers out of range (1e999) do not carry. It tracks the path itself.
class Checker {
 public:
  using number_integer_t = json::number_integer_t;
  using number_unsigned_t = json::number_unsigned_t;
  using number_float_t = json::number_float_t;
  using string_t = json::string_t;
  using binary_t = json::binary_t;

  explicit Checker(const std::string& file) : file_(file) {}

  bool null() { return value(); }
  bool boolean(bool) { return value(); }
  bool number_integer(number_integer_t) { return value(); }
  bool number_unsigned(number_unsigned_t) { return value(); }
  bool number_float(number_float_t, const string_t&) { return value(); }
  bool string(string_t&) { return value(); }
  bool binary(binary_t&) { return value(); }
  bool start_object(std::size_t) { return open(false); }
  bool start_array(std::size_t) { return open(true); }
  bool key(string_t& k) {
    Frame& f = stack_.back();
    f.key = k;
    if (!f.keys.insert(k).second) {
      const std::string p = path(stack_.size() - 1);
      throw SceneError(file_, p.empty() ? "(top level)" : p, "duplicate key " + inQuotes(k));
    }
    return true;
  }
  bool end_object() { return close(); }
  bool end_array() { return close(); }
  bool parse_error(std::size_t position, const std::string& token, const json::exception& e) {
    position_ = position;
    // nlohmann's "[json.exception.parse_error.101] parse error at line 1, column 2: " is dropped.
    std::string what = e.what();
    if (e.id == 406)  // out_of_range.406: a number beyond a double's range
      what = "the number " + inQuotes(token) + " is beyond the range of a double (about 1.8e308); expected a finite number";
    else if (const size_t k = what.find("parse error"); k != std::string::npos)
      if (const size_t colon = what.find(": ", k); colon != std::string::npos) what = what.substr(colon + 2);
    if (what.size() > 200) what = what.substr(0, 200) + "...";
    message_ = "JSON syntax error: " + what;
    return false;
  }

  size_t position() const { return position_; }
  const std::string& message() const { return message_; }

 private:
  struct Frame {
    bool array;
    size_t index;
    std::string key;
    std::set<std::string> keys;
  };
  bool value() {
    if (!stack_.empty() && stack_.back().array) ++stack_.back().index;
    return true;
  }
  bool open(bool array) {
    if (static_cast<int>(stack_.size()) >= limits::kMaxNesting)
      throw SceneError(file_, path(stack_.size()), "arrays and objects nested more than " +
                                                       std::to_string(limits::kMaxNesting) +
                                                       " deep; a scene needs a handful of levels");
    stack_.push_back({array, 0, {}, {}});
    return true;
  }
  bool close() {
    stack_.pop_back();
    return value();
  }
  // Path of the value being read inside the first `depth` containers.
  std::string path(size_t depth) const {
    std::string p;
    for (size_t i = 0; i < depth && i < stack_.size(); ++i)
      p = stack_[i].array ? item(p, stack_[i].index) : join(p, stack_[i].key);
    return p;
  }

  const std::string& file_;
  std::vector<Frame> stack_;
  size_t position_ = 0;
  std::string message_;
};

// "line:column" of byte `pos` (nlohmann counts from 1 and gives the last byte read).
std::string sourcePosition(const std::string& text, size_t pos) {
  pos = std::min(pos > 0 ? pos - 1 : 0, text.size());
  size_t line = 1, lineStart = 0;
  for (size_t i = 0; i < pos; ++i)
    if (text[i] == '\n') {
      ++line;
      lineStart = i + 1;
    }
  return std::to_string(line) + ":" + std::to_string(pos - lineStart + 1);
}

}  // namespace

const std::vector<std::string>& criterionMetrics() {
  static const std::vector<std::string> names = {
      "penetration", "penetration_end", "joint_error", "joint_angle_error", "limit_excess",   "displacement",
      "sideways",    "jitter",      "speed",           "energy_drift", "momentum_drift",   "trajectory_error", "reference_error"};
  return names;
}

const char* referenceKindName(SceneReference::Kind k) {
  switch (k) {
    case SceneReference::Kind::Pendulum: return "pendulum";
    case SceneReference::Kind::FreeFall: return "free_fall";
    case SceneReference::Kind::TorqueFree: return "torque_free";
    case SceneReference::Kind::Converged: return "converged";
  }
  return "?";
}

Scene parseScene(const std::string& text, const std::string& file, const std::string& baseDir,
                 const SceneLimits& lim) {
  Checker checker(file);
  if (!json::sax_parse(text, &checker)) throw SceneError(file, sourcePosition(text, checker.position()), checker.message());
  Scene scene = Reader(file, baseDir, lim).read(json::parse(text));
  scene.hash = contentHash(text);
  scene.text = text;
  scene.baseDir = baseDir;
  return scene;
}

std::string readInputFile(const std::string& path, size_t maxBytes) {
  std::string text;
  if (const std::string why = checkInputFile(path, maxBytes, &text); !why.empty()) throw SceneError(path, "", why);
  return text;
}

std::string checkInputFile(const std::string& path, size_t maxBytes, std::string* contents) {
  if (path.find('\0') != std::string::npos) return "the path holds a NUL character";
  if (path.empty()) return "expected a file name, got an empty one";
  // A FIFO, a terminal or /dev/zero would block or never end: only regular files, checked on
  // the open descriptor (O_NONBLOCK: opening a FIFO does not wait for a writer).
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return std::string("cannot open: ") + std::strerror(errno);
  struct stat st {};
  std::string why;
  if (::fstat(fd, &st) != 0) {
    why = std::string("cannot read: ") + std::strerror(errno);
  } else if (S_ISDIR(st.st_mode)) {
    why = std::string("cannot open: ") + std::strerror(EISDIR);
  } else if (!S_ISREG(st.st_mode)) {
    why = "not a regular file (a pipe, device or socket); give a file";
  } else if (static_cast<unsigned long long>(st.st_size) > maxBytes) {
    why = "the file is " + std::to_string(st.st_size) + " bytes; expected at most " + std::to_string(maxBytes);
  } else if (contents) {
    contents->clear();
    contents->reserve(static_cast<size_t>(st.st_size));
    char buf[1 << 16];
    for (;;) {
      const ssize_t n = ::read(fd, buf, sizeof buf);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) {
        why = std::string("cannot read: ") + std::strerror(errno);
        break;
      }
      if (n == 0) break;
      contents->append(buf, static_cast<size_t>(n));
      if (contents->size() > maxBytes) {  // grew while we read
        why = "the file is more than " + std::to_string(maxBytes) + " bytes";
        break;
      }
    }
  }
  ::close(fd);
  return why;
}

Scene loadScene(const std::string& path, const SceneLimits& lim) {
  namespace fs = std::filesystem;
  const std::string text = readInputFile(path, limits::kMaxSceneBytes);
  const fs::path parent = fs::path(path).parent_path();
  return parseScene(text, path, parent.empty() ? "." : parent.string(), lim);
}

}  // namespace substep

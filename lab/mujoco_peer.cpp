#include "lab/mujoco_peer.h"
#include "lab/peer_shapes.h"

#include "physics/constraints/joints.h"
#include "physics/world.h"

#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <vector>

namespace substep::lab {

namespace {

constexpr double kPi = 3.14159265358979323846;
// MuJoCo 2.2.2 allocates its constraint buffers whole when it makes mjData: efc_J and efc_JT are
// njmax x nv, efc_AR njmax x njmax (dense, even for sparse Jacobians). Scenes whose buffers would
// pass this are refused, as A1 refuses an MLCP too large to form.
constexpr double kBufferBudget = 1.0 * (1u << 30);  // [bytes]
constexpr int kContactsPerGeom = 8;                  // nconmax: a box on a box touches at 4 points, 8 with its neighbours
constexpr size_t kMaxListedPairs = 100000;           // excludes and explicit pairs the MJCF may list
// MuJoCo 2.2.2 reads MJCF with tinyxml2, which refuses elements nested more than 100 deep: a body
// sits inside <mujoco>, <worldbody> and its parents, and holds its geom, joint and inertial.
constexpr int kMaxTreeDepth = 96;

// MuJoCo ends the process on an error by default; here the error ends the run with its message.
// Its warnings (counted in mjData::warning, which the engine reads) are not printed either: the
// default handler would also write MUJOCO_LOG.TXT into the working directory.
void raise(const char* msg) { throw std::runtime_error(std::string("MuJoCo: ") + msg); }
void quiet(const char*) {}

void initMujoco() {
  static std::once_flag once;
  std::call_once(once, [] {
    mju_user_error = raise;
    mju_user_warning = quiet;
  });
}

std::string num(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}
std::string vec(const Vec3& v) { return num(v.x()) + " " + num(v.y()) + " " + num(v.z()); }
std::string quat(const Quat& q) { return num(q.w()) + " " + num(q.x()) + " " + num(q.y()) + " " + num(q.z()); }

// How each body hangs in MuJoCo's tree.
struct Node {
  int parent = -1;      // our body index; -1: the world
  int joint = -1;       // the joint that joins it to the parent (-1: none: a static or free body)
  bool free = false;    // a <freejoint/> body
  std::vector<int> children;
};

struct Tree {
  std::vector<Node> nodes;
  std::vector<int> roots;     // top-level bodies: static ones, then free ones
  std::vector<int> closures;  // joints that close a loop: equalities
  std::string why;            // what does not map, if anything
};

// Joints walked from the static bodies outwards, then from each body no joint reached yet.
Tree buildTree(const Model& model) {
  Tree t;
  const size_t n = model.bodies.size();
  t.nodes.resize(n);
  std::vector<std::vector<int>> incident(n);
  for (size_t k = 0; k < model.joints.size(); ++k) {
    const Joint& j = model.joints[k];
    incident[static_cast<size_t>(j.bodyA)].push_back(static_cast<int>(k));
    incident[static_cast<size_t>(j.bodyB)].push_back(static_cast<int>(k));
  }
  std::vector<bool> reached(n, false), used(model.joints.size(), false);
  std::deque<int> queue;
  auto walk = [&] {
    while (!queue.empty()) {
      const int u = queue.front();
      queue.pop_front();
      for (int k : incident[static_cast<size_t>(u)]) {
        if (used[static_cast<size_t>(k)]) continue;
        used[static_cast<size_t>(k)] = true;
        const Joint& j = model.joints[static_cast<size_t>(k)];
        const int v = j.bodyA == u ? j.bodyB : j.bodyA;
        if (reached[static_cast<size_t>(v)]) {
          if (!(model.bodies[static_cast<size_t>(u)].isStatic && model.bodies[static_cast<size_t>(v)].isStatic))
            t.closures.push_back(k);
          continue;
        }
        reached[static_cast<size_t>(v)] = true;
        t.nodes[static_cast<size_t>(v)].parent = u;
        t.nodes[static_cast<size_t>(v)].joint = k;
        t.nodes[static_cast<size_t>(u)].children.push_back(v);
        queue.push_back(v);
      }
    }
  };
  for (size_t i = 0; i < n; ++i)
    if (model.bodies[i].isStatic) {
      reached[i] = true;
      t.roots.push_back(static_cast<int>(i));
      queue.push_back(static_cast<int>(i));
    }
  walk();
  for (size_t i = 0; i < n; ++i)
    if (!reached[i]) {
      reached[i] = true;
      t.nodes[i].free = true;
      t.roots.push_back(static_cast<int>(i));
      queue.push_back(static_cast<int>(i));
      walk();
    }
  for (int k : t.closures) {
    const Joint& j = model.joints[static_cast<size_t>(k)];
    if (j.type == JointType::Hinge)
      return t.why = "hinge \"" + j.name + "\" closes a loop of joints (MuJoCo's joints are a tree; a ball or fixed joint "
                     "closing a loop is an equality, a hinge has none)",
             t;
  }
  return t;
}

// Our hinge angle at the start, and the sign of MuJoCo's angle against ours: +1 when the child is
// B (its angle is B's turn from A, as ours), -1 when it is A.
double hingeStart(const Joint& j, const State& s) {
  return hingeAngle(j, s.bodies[static_cast<size_t>(j.bodyA)].pose(), s.bodies[static_cast<size_t>(j.bodyB)].pose());
}

// Velocities the joints must allow at the start: MuJoCo's coordinates are the joints', so a
// parent and child moving apart across a joint cannot be represented.
std::string velocityMismatch(const Model& model, const State& s, const Tree& t) {
  for (size_t c = 0; c < t.nodes.size(); ++c) {
    const Node& node = t.nodes[c];
    if (node.joint < 0 || model.bodies[c].isStatic) continue;
    const Joint& j = model.joints[static_cast<size_t>(node.joint)];
    const BodyState& C = s.bodies[c];
    const BodyState& P = s.bodies[static_cast<size_t>(node.parent)];
    const bool pStatic = model.bodies[static_cast<size_t>(node.parent)].isStatic;
    const Vec3 wC = C.worldAngularVelocity(), wP = pStatic ? Vec3::Zero() : P.worldAngularVelocity();
    const Vec3 vP = pStatic ? Vec3::Zero() : P.v;
    const Vec3 anchor = (static_cast<size_t>(j.bodyB) == c ? C.pose().apply(j.localAnchorB) : C.pose().apply(j.localAnchorA));
    const Vec3 atC = C.v + wC.cross(anchor - C.x), atP = vP + wP.cross(anchor - P.x);
    const double scale = 1e-6 * (1 + C.v.norm() + vP.norm() + wC.norm() + wP.norm());
    Vec3 rel = wC - wP;
    if (j.type == JointType::Hinge) {
      const Vec3 axis = P.pose().rotate(static_cast<size_t>(j.bodyA) == c ? j.localAxisB : j.localAxisA).normalized();
      rel -= rel.dot(axis) * axis;
    }
    const bool turns = j.type == JointType::Ball ? false : rel.norm() > scale;
    if ((atC - atP).norm() > scale || turns)
      return "body \"" + model.bodies[c].name + "\" starts moving apart from \"" + model.bodies[static_cast<size_t>(node.parent)].name +
             "\" across joint \"" + j.name + "\" (MuJoCo's coordinates are its joints')";
  }
  return {};
}

struct Sizes {
  int nconmax = 0, njmax = 0, nv = 0;
  double bytes() const {
    const double J = static_cast<double>(njmax) * nv, AR = static_cast<double>(njmax) * njmax;
    return 24 * J + 12 * AR;  // J and JT (values and column indices), AR (values and indices)
  }
};

Sizes sizesOf(const Model& model, const Tree& t) {
  Sizes s;
  int geoms = 0, rows = 50;
  for (size_t i = 0; i < model.bodies.size(); ++i) {
    ++geoms;
    if (model.bodies[i].isStatic) continue;
    const Node& n = t.nodes[i];
    if (n.free) s.nv += 6;
    if (n.joint >= 0) {
      const Joint& j = model.joints[static_cast<size_t>(n.joint)];
      s.nv += j.type == JointType::Ball ? 3 : j.type == JointType::Hinge ? 1 : 0;
      if (j.hasLimits) rows += 1;
    }
  }
  for (int k : t.closures) rows += model.joints[static_cast<size_t>(k)].type == JointType::Fixed ? 6 : 3;
  s.nconmax = 100 + kContactsPerGeom * geoms;
  s.njmax = rows + 4 * s.nconmax;  // a pyramidal contact of condim 3 is 4 rows (elliptic: 3)
  return s;
}

// The pairs our filter keeps apart (model.h's mayTouch, joints without `collide`), among pairs that
// are not both static (MuJoCo never collides two bodies welded to the world).
std::vector<std::pair<int, int>> excludedPairs(const Model& model, size_t limit, bool& tooMany) {
  std::vector<std::pair<int, int>> out;
  tooMany = false;
  const size_t n = model.bodies.size();
  for (const Joint& j : model.joints)
    if (!j.collide) out.emplace_back(std::min(j.bodyA, j.bodyB), std::max(j.bodyA, j.bodyB));
  for (size_t a = 0; a < n; ++a)
    for (size_t b = a + 1; b < n; ++b) {
      const Body &A = model.bodies[a], &B = model.bodies[b];
      if ((A.isStatic && B.isStatic) || mayTouch(A, B)) continue;
      out.emplace_back(static_cast<int>(a), static_cast<int>(b));
      if (out.size() > limit) return tooMany = true, out;
    }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

// Pairs that may touch whose frictions differ: MuJoCo would take the larger, we the geometric mean.
std::vector<std::pair<int, int>> frictionPairs(const Model& model, const std::vector<std::pair<int, int>>& excluded, size_t limit,
                                               bool& tooMany) {
  std::vector<std::pair<int, int>> out;
  tooMany = false;
  const size_t n = model.bodies.size();
  for (size_t a = 0; a < n; ++a)
    for (size_t b = a + 1; b < n; ++b) {
      const Body &A = model.bodies[a], &B = model.bodies[b];
      if ((A.isStatic && B.isStatic) || A.friction == B.friction) continue;
      if (std::binary_search(excluded.begin(), excluded.end(), std::make_pair(static_cast<int>(a), static_cast<int>(b)))) continue;
      out.emplace_back(static_cast<int>(a), static_cast<int>(b));
      if (out.size() > limit) return tooMany = true, out;
    }
  return out;
}

std::string modelUnsupported(const Model& model) {
  if (std::string why = unmappedBody(model, "MuJoCo"); !why.empty()) return why;
  for (const Body& b : model.bodies) {
    if (b.restitution > 0)
      return "body \"" + b.name + "\" has restitution " + num(b.restitution) +
             " (MuJoCo has no coefficient of restitution: its contacts are damped springs)";
    if (!b.isStatic) {
      const Vec3& I = b.inertia;
      if (I.x() + I.y() < I.z() || I.y() + I.z() < I.x() || I.z() + I.x() < I.y())
        return "body \"" + b.name + "\": its moments of inertia break the triangle inequality, which MuJoCo requires";
    }
  }
  for (const Joint& j : model.joints) {
    if (j.type == JointType::ConeTwist)
      return "joint \"" + j.name + "\" is a cone_twist (MuJoCo's ball limit is one cone on the whole turn; the MuJoCo "
             "peer maps ball, hinge and fixed joints)";
    if (j.type == JointType::Spring || j.type == JointType::Motor)
      return "joint \"" + j.name + "\" is a " + jointTypeName(j.type) + " (the MuJoCo peer maps ball, hinge and fixed joints)";
    if (j.type == JointType::Hinge && j.hasMotor) return "joint \"" + j.name + "\" is a hinge with a motor (not mapped)";
    if (j.type == JointType::Fixed && j.collide)
      return "fixed joint \"" + j.name + "\" lets its bodies collide (MuJoCo never collides bodies welded together)";
  }
  return {};
}

}  // namespace

// The most bodies on one path from a top-level body down MuJoCo's tree.
int treeDepth(const Tree& t) {
  int deepest = 0;
  std::vector<std::pair<int, int>> stack;  // (body, its depth)
  for (int r : t.roots) stack.emplace_back(r, 1);
  while (!stack.empty()) {
    const auto [u, d] = stack.back();
    stack.pop_back();
    deepest = std::max(deepest, d);
    for (int c : t.nodes[static_cast<size_t>(u)].children) stack.emplace_back(c, d + 1);
  }
  return deepest;
}

std::string mujocoUnsupported(const Model& model, const State& initial) {
  if (std::string why = modelUnsupported(model); !why.empty()) return why;
  const Tree t = buildTree(model);
  if (!t.why.empty()) return t.why;
  if (const int depth = treeDepth(t); depth > kMaxTreeDepth)
    return "its joints chain " + std::to_string(depth) + " bodies deep (MuJoCo 2.2.2 reads a scene as XML nested at most 100 "
           "elements deep: " + std::to_string(kMaxTreeDepth) + " bodies)";
  if (std::string why = velocityMismatch(model, initial, t); !why.empty()) return why;
  const Sizes s = sizesOf(model, t);
  if (s.bytes() > kBufferBudget) {
    char buf[200];
    std::snprintf(buf, sizeof buf, "%.1f GB for %d contacts and %d constraint rows over %d degrees of freedom",
                  s.bytes() / 1e9, s.nconmax, s.njmax, s.nv);
    return std::string("too large for MuJoCo 2.2.2, whose constraint buffers are dense: ") + buf + " (the peer allows " +
           num(kBufferBudget / 1e9).substr(0, 4) + " GB)";
  }
  bool tooMany = false;
  const auto excluded = excludedPairs(model, kMaxListedPairs, tooMany);
  if (tooMany) return "more than " + std::to_string(kMaxListedPairs) + " pairs of bodies that must not touch (MuJoCo lists each)";
  frictionPairs(model, excluded, kMaxListedPairs, tooMany);
  if (tooMany)
    return "more than " + std::to_string(kMaxListedPairs) + " pairs of bodies with different frictions (MuJoCo combines by the larger; "
           "the peer lists each pair with ours)";
  return {};
}

std::string mujocoVersion() { return mj_versionString(); }

std::string mujocoXml(const Model& model, const State& initial, const MujocoSettings& settings) {
  if (const std::string why = mujocoUnsupported(model, initial); !why.empty()) throw std::invalid_argument("MuJoCo peer: " + why);
  const Tree t = buildTree(model);
  const Sizes sizes = sizesOf(model, t);
  const char* solvers[] = {"Newton", "CG", "PGS"};
  const char* integrators[] = {"Euler", "RK4", "implicit"};
  const std::string margin = "margin=\"" + num(settings.margin) + "\" gap=\"" + num(settings.margin) + "\"";
  std::string x;
  x += "<mujoco model=\"substep\">\n";
  // inertiafromgeom false: every dynamic body gives its own <inertial>, static ones have none.
  x += "<compiler angle=\"radian\" inertiafromgeom=\"false\" fusestatic=\"false\"/>\n";
  x += "<option timestep=\"" + num(settings.dt) + "\" gravity=\"" + vec(model.gravity) + "\" iterations=\"" +
       std::to_string(settings.iterations) + "\" solver=\"" + solvers[settings.solver] + "\" integrator=\"" +
       integrators[settings.integrator] + "\" cone=\"" + (settings.elliptic ? "elliptic" : "pyramidal") + "\">\n";
  // Which pairs collide is our filter's, listed below: parents and children are not spared.
  x += "<flag filterparent=\"disable\"/>\n</option>\n";
  x += "<size nconmax=\"" + std::to_string(sizes.nconmax) + "\" njmax=\"" + std::to_string(sizes.njmax) + "\"/>\n";
  x += "<worldbody>\n";
  const Quat turn(Eigen::AngleAxisd(-kPi / 2, Vec3::UnitX()));  // MuJoCo's capsule axis (Z) onto ours (Y)
  auto geom = [&](size_t i) {
    const Body& b = model.bodies[i];
    const Shape& s = b.shape;
    std::string g = "<geom name=\"g" + std::to_string(i) + "\" condim=\"3\" friction=\"" + num(b.friction) + " 0.005 0.0001\" " + margin;
    switch (s.type) {
      case ShapeType::Sphere: g += " type=\"sphere\" size=\"" + num(s.radius) + "\""; break;
      case ShapeType::Box: g += " type=\"box\" size=\"" + vec(s.halfExtents) + "\""; break;
      case ShapeType::Capsule:
        g += " type=\"capsule\" size=\"" + num(s.radius) + " " + num(s.halfHeight) + "\" quat=\"" + quat(turn) + "\"";
        break;
      case ShapeType::Cylinder:
        g += " type=\"cylinder\" size=\"" + num(s.radius) + " " + num(s.halfHeight) + "\" quat=\"" + quat(turn) + "\"";
        break;
      case ShapeType::Plane: {  // MuJoCo's plane is z >= 0 in its frame: turned onto our normal, moved to our offset
        const Vec3 n = s.normal.normalized();
        const Quat q = Quat::FromTwoVectors(Vec3::UnitZ(), n);
        g += " type=\"plane\" size=\"0 0 1\" pos=\"" + vec(s.offset * n) + "\" quat=\"" + quat(q) + "\"";
        break;
      }
      default: break;
    }
    return g + "/>\n";
  };
  // Bodies in the frame of their parent; the world's frame for the top level.
  std::function<void(int)> body = [&](int i) {
    const size_t u = static_cast<size_t>(i);
    const Node& n = t.nodes[u];
    const Body& b = model.bodies[u];
    Pose rel = initial.bodies[u].pose();
    rel.q.normalize();
    if (n.parent >= 0 && !n.free) {
      Pose P = initial.bodies[static_cast<size_t>(n.parent)].pose();
      P.q.normalize();
      rel = Pose{P.unrotate(rel.p - P.p), P.q.conjugate() * rel.q};
    }
    x += "<body name=\"b" + std::to_string(i) + "\" pos=\"" + vec(rel.p) + "\" quat=\"" + quat(rel.q) + "\">\n";
    if (n.free) x += "<freejoint/>\n";
    if (n.joint >= 0 && !b.isStatic) {
      const Joint& j = model.joints[static_cast<size_t>(n.joint)];
      const bool childIsB = static_cast<size_t>(j.bodyB) == u;
      const Vec3 anchor = childIsB ? j.localAnchorB : j.localAnchorA;
      if (j.type == JointType::Ball) x += "<joint type=\"ball\" pos=\"" + vec(anchor) + "\"/>\n";
      if (j.type == JointType::Hinge) {
        const Vec3 axis = (childIsB ? j.localAxisB : j.localAxisA).normalized();
        x += "<joint type=\"hinge\" pos=\"" + vec(anchor) + "\" axis=\"" + vec(axis) + "\"";
        if (j.hasLimits) {
          // MuJoCo's angle is 0 at the start and is the child's turn from the parent: ours minus its
          // start when the child is B, the negative of that when it is A.
          const double a0 = hingeStart(j, initial);
          const double lo = childIsB ? j.lower - a0 : a0 - j.upper, hi = childIsB ? j.upper - a0 : a0 - j.lower;
          x += " limited=\"true\" range=\"" + num(lo) + " " + num(hi) + "\"";
        }
        x += "/>\n";
      }
      // Fixed: no joint, the child is welded to its parent.
    }
    if (!b.isStatic)
      x += "<inertial pos=\"0 0 0\" mass=\"" + num(b.mass) + "\" diaginertia=\"" + vec(b.inertia) + "\"/>\n";
    x += geom(u);
    for (int c : n.children) body(c);
    x += "</body>\n";
  };
  for (int r : t.roots) body(r);
  x += "</worldbody>\n";

  bool tooMany = false;
  const auto excluded = excludedPairs(model, kMaxListedPairs, tooMany);
  const auto pairs = frictionPairs(model, excluded, kMaxListedPairs, tooMany);
  if (!excluded.empty() || !pairs.empty()) {
    x += "<contact>\n";
    for (const auto& [a, b] : excluded)
      if (!(model.bodies[static_cast<size_t>(a)].isStatic && model.bodies[static_cast<size_t>(b)].isStatic))
        x += "<exclude body1=\"b" + std::to_string(a) + "\" body2=\"b" + std::to_string(b) + "\"/>\n";
    for (const auto& [a, b] : pairs) {
      const double mu = std::sqrt(model.bodies[static_cast<size_t>(a)].friction * model.bodies[static_cast<size_t>(b)].friction);
      x += "<pair geom1=\"g" + std::to_string(a) + "\" geom2=\"g" + std::to_string(b) + "\" condim=\"3\" friction=\"" + num(mu) +
           " " + num(mu) + " 0.005 0.0001 0.0001\" " + margin + "/>\n";
    }
    x += "</contact>\n";
  }
  if (!t.closures.empty()) {
    x += "<equality>\n";
    for (int k : t.closures) {
      const Joint& j = model.joints[static_cast<size_t>(k)];
      const std::string bodies = "body1=\"b" + std::to_string(j.bodyA) + "\" body2=\"b" + std::to_string(j.bodyB) + "\"";
      if (j.type == JointType::Ball) x += "<connect " + bodies + " anchor=\"" + vec(j.localAnchorA) + "\"/>\n";
      if (j.type == JointType::Fixed) x += "<weld " + bodies + "/>\n";  // holds the start's relative pose
    }
    x += "</equality>\n";
  }
  x += "</mujoco>\n";
  return x;
}

namespace {

class MujocoEngine final : public Engine {
 public:
  MujocoEngine(const Model& model, const State& initial, const MujocoSettings& settings);
  ~MujocoEngine() override {
    if (d_) mj_deleteData(d_);
    if (m_) mj_deleteModel(m_);
  }
  MujocoEngine(const MujocoEngine&) = delete;
  MujocoEngine& operator=(const MujocoEngine&) = delete;

  void advance() override {
    try {
      mj_step(m_, d_);
    } catch (const std::runtime_error& e) {  // raise(): MuJoCo's state is not to be stepped again
      failed_ = e.what();
      return;
    }
    // A full contact list drops contacts: the scene needs more than the peer made room for.
    if (d_->warning[mjWARN_CONTACTFULL].number > 0 || d_->warning[mjWARN_CNSTRFULL].number > 0)
      throw Refused("MuJoCo's contact buffers are full (" + std::to_string(m_->nconmax) + " contacts, " +
                    std::to_string(m_->njmax) + " rows: the peer makes room for " + std::to_string(kContactsPerGeom) +
                    " contacts a body)");
  }
  Step status() override;
  const State& state() const override { return s_; }
  // The depths at the current coordinates: MuJoCo's collision run again (not timed) after the step,
  // whose own contacts are those of the step's start.
  ContactDepths depths() const override {
    ContactDepths c;
    mj_collision(m_, d_);
    for (int k = 0; k < d_->ncon; ++k) {
      const double depth = -d_->contact[k].dist;
      if (depth <= 0) continue;
      c.deepest = std::max(c.deepest, depth);
      c.sumSquares += depth * depth;
      ++c.points;
    }
    return c;
  }

 private:
  mjModel* m_ = nullptr;
  mjData* d_ = nullptr;
  std::vector<int> ids_;  // MuJoCo's body id of each of our bodies
  std::vector<bool> static_;
  State s_;
  double dt_;
  int badNumbers_ = 0;  // MuJoCo's warnings of bad qpos, qvel, qacc so far
  std::string failed_;
};

MujocoEngine::MujocoEngine(const Model& model, const State& initial, const MujocoSettings& settings) : s_(initial), dt_(settings.dt) {
  initMujoco();
  const std::string xml = mujocoXml(model, initial, settings);  // throws for what does not map
  // 2.2.2 loads only files: the MJCF goes into a virtual file system (two megabytes of tables).
  auto vfs = std::make_unique<mjVFS>();
  mj_defaultVFS(vfs.get());
  if (mj_makeEmptyFileVFS(vfs.get(), "scene.xml", static_cast<int>(xml.size())) != 0)
    throw std::runtime_error("MuJoCo peer: could not make its virtual file");
  const int f = mj_findFileVFS(vfs.get(), "scene.xml");
  std::memcpy(vfs->filedata[f], xml.data(), xml.size());
  char error[1000] = "";
  try {
    m_ = mj_loadXML("scene.xml", vfs.get(), error, sizeof error);
  } catch (...) {
    mj_deleteVFS(vfs.get());
    throw;
  }
  mj_deleteVFS(vfs.get());
  if (!m_) throw std::invalid_argument(std::string("MuJoCo peer: MuJoCo did not load the scene: ") + error);
  d_ = mj_makeData(m_);
  if (!d_) throw std::runtime_error("MuJoCo peer: mj_makeData failed (out of memory?)");

  const Tree t = buildTree(model);
  for (size_t i = 0; i < model.bodies.size(); ++i) {
    ids_.push_back(mj_name2id(m_, mjOBJ_BODY, ("b" + std::to_string(i)).c_str()));
    static_.push_back(model.bodies[i].isStatic);
  }
  // The start's velocities in MuJoCo's coordinates: a free body's linear (world) and angular (body
  // frame) velocity; a ball's relative angular velocity in the child's frame; a hinge's rate.
  for (size_t i = 0; i < model.bodies.size(); ++i) {
    if (model.bodies[i].isStatic) continue;
    const int body = ids_[i];
    if (m_->body_jntnum[body] == 0) continue;  // welded
    const int jnt = m_->body_jntadr[body];
    mjtNum* qv = d_->qvel + m_->jnt_dofadr[jnt];
    const BodyState& c = initial.bodies[i];
    const Node& n = t.nodes[i];
    if (n.free) {
      for (int k = 0; k < 3; ++k) {
        qv[k] = c.v[k];
        qv[3 + k] = c.w[k];
      }
      continue;
    }
    const bool parentStatic = model.bodies[static_cast<size_t>(n.parent)].isStatic;
    const Vec3 wP = parentStatic ? Vec3::Zero() : initial.bodies[static_cast<size_t>(n.parent)].worldAngularVelocity();
    const Vec3 rel = c.worldAngularVelocity() - wP;
    const Joint& j = model.joints[static_cast<size_t>(n.joint)];
    if (j.type == JointType::Ball) {
      const Vec3 local = c.q.normalized().conjugate() * rel;
      for (int k = 0; k < 3; ++k) qv[k] = local[k];
    } else if (j.type == JointType::Hinge) {
      const bool childIsB = static_cast<size_t>(j.bodyB) == i;
      const Vec3 axis = c.q.normalized() * (childIsB ? j.localAxisB : j.localAxisA).normalized();
      qv[0] = rel.dot(axis);
    }
  }
  mj_forward(m_, d_);
}

Engine::Step MujocoEngine::status() {
  if (!failed_.empty()) return Step{false, false, failed_};
  const int bad = d_->warning[mjWARN_BADQPOS].number + d_->warning[mjWARN_BADQVEL].number + d_->warning[mjWARN_BADQACC].number;
  if (bad > badNumbers_)  // MuJoCo then resets its state to the start: the run is over
    return Step{false, false, "MuJoCo found a bad number in its state or accelerations and reset it"};
  // mj_step leaves the positions of the step's start in xpos and xquat: the new ones from qpos.
  mj_kinematics(m_, d_);
  mj_comPos(m_, d_);
  mj_comVel(m_, d_);
  for (size_t i = 0; i < ids_.size(); ++i) {
    if (static_[i]) continue;
    const int b = ids_[i];
    BodyState& s = s_.bodies[i];
    const mjtNum* x = d_->xpos + 3 * b;
    const mjtNum* q = d_->xquat + 4 * b;
    s.x = Vec3(x[0], x[1], x[2]);
    s.q = Quat(q[0], q[1], q[2], q[3]).normalized();
    mjtNum v[6];  // in the body's frame: angular, then linear at the body's origin (our centre of mass)
    mj_objectVelocity(m_, d_, mjOBJ_BODY, b, v, 1);
    s.w = Vec3(v[0], v[1], v[2]);
    s.v = s.q * Vec3(v[3], v[4], v[5]);
  }
  s_.step += 1;
  s_.time = static_cast<double>(s_.step) * dt_;
  if (s_.finite()) return {};
  return Step{false, false, "a MuJoCo body's state is not finite"};
}

}  // namespace

std::unique_ptr<Engine> makeMujocoEngine(const Model& model, const State& initial, const MujocoSettings& settings) {
  return std::make_unique<MujocoEngine>(model, initial, settings);
}

}  // namespace substep::lab

#include "physics/generators.h"

#include "physics/mass.h"

#include <cmath>
#include <stdexcept>

namespace substep {

const std::vector<GeneratorInfo>& generatorList() {
  static const std::vector<GeneratorInfo> list = {
      {"stack", "count boxes one on another: half_extents, position (bottom face), gap (vertical)"},
      {"pyramid", "levels rows of boxes along X, one fewer per row (20 levels = 210): half_extents, position, gap"},
      {"chain", "count links (capsule, box or sphere) jointed to a static anchor: link, anchor, direction, spacing"},
      {"ragdoll", "count humanoid ragdolls of 14 bodies and 13 limited joints, in layers of columns: position "
                  "(pelvis), orientation, offset (per layer), spread (per column), yaw, velocity, scale, mass"},
  };
  return list;
}

namespace {

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

void checkMaterial(const BodyMaterial& m) {
  require(!m.mass || *m.mass > 0, "mass must be > 0");
  require(m.density > 0, "density must be > 0");
  require(m.friction >= 0, "friction must be >= 0");
  require(m.restitution >= 0 && m.restitution <= 1, "restitution must be in [0, 1]");
}

Body makeDynamic(const std::string& name, const Shape& shape, const BodyMaterial& m) {
  Body b;
  b.name = name;
  b.shape = shape;
  b.friction = m.friction;
  b.restitution = m.restitution;
  b.group = m.group;
  b.category = m.category;
  b.mask = m.mask;
  b.filterGroup = m.filterGroup;
  if (m.mass)
    setMassFromMass(b, *m.mass);
  else
    setMassFromDensity(b, m.density);
  return b;
}

Shape boxShape(const Vec3& halfExtents) {
  Shape s;
  s.type = ShapeType::Box;
  s.halfExtents = halfExtents;
  return s;
}

BodyState at(const Vec3& x, const Quat& q = Quat::Identity()) {
  BodyState s;
  s.x = x;
  s.q = q;
  return s;
}

}  // namespace

int addBody(Scene& scene, const Body& body, const BodyState& state) {
  scene.model.bodies.push_back(body);
  scene.initial.bodies.push_back(state);
  return static_cast<int>(scene.model.bodies.size()) - 1;
}

Joint makeJoint(const Scene& scene, JointType type, int a, int b, const Vec3& worldAnchorA, const Vec3& worldAnchorB,
                const Vec3& worldAxis) {
  const BodyState& sa = scene.initial.bodies.at(a);
  const BodyState& sb = scene.initial.bodies.at(b);
  Joint j;
  j.type = type;
  j.bodyA = a;
  j.bodyB = b;
  j.localAnchorA = sa.q.conjugate() * (worldAnchorA - sa.x);
  j.localAnchorB = sb.q.conjugate() * (worldAnchorB - sb.x);
  const Vec3 axis = worldAxis.normalized();
  Vec3 ref, unused;
  tangentBasis(axis, ref, unused);
  // The same world vectors in both frames: the joint starts at zero angle.
  j.localAxisA = sa.q.conjugate() * axis;
  j.localAxisB = sb.q.conjugate() * axis;
  j.localRefA = sa.q.conjugate() * ref;
  j.localRefB = sb.q.conjugate() * ref;
  j.restLength = (worldAnchorB - worldAnchorA).norm();
  return j;
}

void addStack(Scene& scene, const StackParams& p) {
  require(p.count >= 1, "stack: count must be >= 1");
  require((p.halfExtents.array() > 0).all(), "stack: half_extents must be > 0");
  require(p.gap >= 0, "stack: gap must be >= 0");
  checkMaterial(p.material);
  const Shape shape = boxShape(p.halfExtents);
  const double h = p.halfExtents.y();
  for (int k = 0; k < p.count; ++k) {
    const Vec3 x = p.position + Vec3(0, h + k * (2 * h + p.gap), 0);
    addBody(scene, makeDynamic(p.name + "_" + std::to_string(k), shape, p.material), at(x));
  }
}

void addPyramid(Scene& scene, const PyramidParams& p) {
  require(p.levels >= 1, "pyramid: levels must be >= 1");
  require((p.halfExtents.array() > 0).all(), "pyramid: half_extents must be > 0");
  require(p.gap >= 0, "pyramid: gap must be >= 0");
  checkMaterial(p.material);
  const Shape shape = boxShape(p.halfExtents);
  const double pitch = 2 * p.halfExtents.x() + p.gap;  // centre to centre along X
  const double h = p.halfExtents.y();
  for (int level = 0; level < p.levels; ++level) {
    const int n = p.levels - level;
    for (int i = 0; i < n; ++i) {
      const double x = (i - 0.5 * (n - 1)) * pitch;
      const Vec3 c = p.position + Vec3(x, h + level * 2 * h, 0);
      addBody(scene, makeDynamic(p.name + "_" + std::to_string(level) + "_" + std::to_string(i), shape, p.material),
              at(c));
    }
  }
}

void addChain(Scene& scene, const ChainParams& p) {
  require(p.count >= 1, "chain: count must be >= 1");
  require(p.spacing > 0, "chain: spacing must be > 0");
  require(p.direction.norm() > 1e-9, "chain: direction must not be zero");
  require(p.link.type == ShapeType::Capsule || p.link.type == ShapeType::Box || p.link.type == ShapeType::Sphere,
          "chain: link must be a capsule, box or sphere");
  require(p.joint == JointType::Ball || p.joint == JointType::Hinge, "chain: joint must be ball or hinge");
  require(p.anchorRadius > 0, "chain: anchor radius must be > 0");
  checkMaterial(p.material);

  const Vec3 d = p.direction.normalized();
  const Quat q = Quat::FromTwoVectors(Vec3::UnitY(), d).normalized();  // local Y (capsule axis) along d
  // Hinge axis: horizontal and across the chain, so a horizontal chain swings in its vertical plane.
  Vec3 axis = d.cross(Vec3::UnitY());
  if (axis.norm() < 1e-6) axis = Vec3::UnitZ();  // a vertical chain: any horizontal axis
  axis.normalize();

  Body anchor;
  anchor.name = p.name + "_anchor";
  anchor.isStatic = true;
  anchor.shape.type = ShapeType::Sphere;
  anchor.shape.radius = p.anchorRadius;
  anchor.friction = p.material.friction;
  anchor.restitution = p.material.restitution;
  anchor.group = p.material.group;
  anchor.category = p.material.category;
  anchor.mask = p.material.mask;
  anchor.filterGroup = p.material.filterGroup;
  int prev = addBody(scene, anchor, at(p.anchor));

  for (int k = 0; k < p.count; ++k) {
    const Vec3 c = p.anchor + (k + 0.5) * p.spacing * d;
    const int link = addBody(scene, makeDynamic(p.name + "_" + std::to_string(k), p.link, p.material), at(c, q));
    const Vec3 pivot = p.anchor + k * p.spacing * d;
    Joint j = makeJoint(scene, p.joint, prev, link, pivot, pivot, axis);
    j.name = p.name + "_joint_" + std::to_string(k);
    j.collide = false;
    scene.model.joints.push_back(j);
    prev = link;
  }
}

namespace {

// One part of the ragdoll in its own frame at scale 1: Y up, facing +Z, pelvis centre at 0.
struct Part {
  const char* name;
  Shape shape;
  Vec3 centre;
  double mass;  // share of 68 kg [kg]
};

Shape capsuleY(double r, double hh) {
  Shape s;
  s.type = ShapeType::Capsule;
  s.radius = r;
  s.halfHeight = hh;
  return s;
}
Shape sphereShape(double r) {
  Shape s;
  s.type = ShapeType::Sphere;
  s.radius = r;
  return s;
}

const std::vector<Part>& parts() {
  // Segment masses after de Leva's adult tables, rounded (sum 68 kg).
  static const std::vector<Part> p = {
      {"pelvis", boxShape(Vec3(0.16, 0.10, 0.10)), Vec3(0, 0, 0), 10},
      {"spine", capsuleY(0.11, 0.06), Vec3(0, 0.24, 0), 8},
      {"chest", boxShape(Vec3(0.18, 0.13, 0.11)), Vec3(0, 0.52, 0), 15},
      {"head", sphereShape(0.11), Vec3(0, 0.80, 0), 5},
      {"upper_arm_l", capsuleY(0.05, 0.11), Vec3(0.26, 0.44, 0), 2},
      {"upper_arm_r", capsuleY(0.05, 0.11), Vec3(-0.26, 0.44, 0), 2},
      {"forearm_l", capsuleY(0.045, 0.12), Vec3(0.26, 0.12, 0), 1},
      {"forearm_r", capsuleY(0.045, 0.12), Vec3(-0.26, 0.12, 0), 1},
      {"thigh_l", capsuleY(0.075, 0.15), Vec3(0.10, -0.30, 0), 7},
      {"thigh_r", capsuleY(0.075, 0.15), Vec3(-0.10, -0.30, 0), 7},
      {"shin_l", capsuleY(0.055, 0.16), Vec3(0.10, -0.74, 0), 3.5},
      {"shin_r", capsuleY(0.055, 0.16), Vec3(-0.10, -0.74, 0), 3.5},
      {"foot_l", boxShape(Vec3(0.05, 0.035, 0.11)), Vec3(0.10, -1.00, 0.05), 1},
      {"foot_r", boxShape(Vec3(0.05, 0.035, 0.11)), Vec3(-0.10, -1.00, 0.05), 1},
  };
  return p;
}

struct JointSpec {
  JointType type;
  int a, b;      // indices in parts()
  Vec3 anchor;   // ragdoll frame, scale 1
  Vec3 axis;     // twist axis (cone-twist) or hinge axis
  double lower, upper, swing;
};

const std::vector<JointSpec>& joints() {
  const Vec3 down(0, -1, 0), up(0, 1, 0), side(1, 0, 0);
  // Hinges: a positive angle turns B about the axis relative to A. About +X a shin hanging
  // down swings backwards (the knee bends), about -X a forearm swings forwards (the elbow).
  static const std::vector<JointSpec> j = {
      {JointType::ConeTwist, 0, 1, Vec3(0, 0.10, 0), up, -0.30, 0.30, 0.45},          // lower back
      {JointType::ConeTwist, 1, 2, Vec3(0, 0.39, 0), up, -0.30, 0.30, 0.40},          // upper back
      {JointType::ConeTwist, 2, 3, Vec3(0, 0.68, 0), up, -0.90, 0.90, 0.60},          // neck
      {JointType::ConeTwist, 2, 4, Vec3(0.26, 0.60, 0), down, -0.80, 0.80, 1.50},     // shoulders
      {JointType::ConeTwist, 2, 5, Vec3(-0.26, 0.60, 0), down, -0.80, 0.80, 1.50},
      {JointType::Hinge, 4, 6, Vec3(0.26, 0.28, 0), -side, 0.0, 2.50, 0},            // elbows
      {JointType::Hinge, 5, 7, Vec3(-0.26, 0.28, 0), -side, 0.0, 2.50, 0},
      {JointType::ConeTwist, 0, 8, Vec3(0.10, -0.08, 0), down, -0.50, 0.50, 1.20},    // hips
      {JointType::ConeTwist, 0, 9, Vec3(-0.10, -0.08, 0), down, -0.50, 0.50, 1.20},
      {JointType::Hinge, 8, 10, Vec3(0.10, -0.52, 0), side, 0.0, 2.40, 0},           // knees
      {JointType::Hinge, 9, 11, Vec3(-0.10, -0.52, 0), side, 0.0, 2.40, 0},
      {JointType::Hinge, 10, 12, Vec3(0.10, -0.96, 0), side, -0.70, 0.50, 0},        // ankles
      {JointType::Hinge, 11, 13, Vec3(-0.10, -0.96, 0), side, -0.70, 0.50, 0},
  };
  return j;
}

Shape scaled(Shape s, double k) {
  s.radius *= k;
  s.halfHeight *= k;
  s.halfExtents *= k;
  return s;
}

}  // namespace

const std::vector<std::string>& ragdollParts() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const Part& p : parts()) n.push_back(p.name);
    return n;
  }();
  return names;
}

void addRagdoll(Scene& scene, const RagdollParams& p) {
  require(p.count >= 1, "ragdoll: count must be >= 1");
  require(p.scale > 0, "ragdoll: scale must be > 0");
  require(p.mass > 0, "ragdoll: mass must be > 0");
  checkMaterial(p.material);
  double total = 0;
  for (const Part& part : parts()) total += part.mass;
  const double massScale = p.mass / total * p.scale * p.scale * p.scale;
  require(p.columns >= 1, "ragdoll: columns must be >= 1");
  for (int k = 0; k < p.count; ++k) {
    const int layer = k / p.columns, column = k % p.columns;
    const Quat turn(Eigen::AngleAxisd(layer * p.yaw, Vec3::UnitY()));
    const Quat q = turn * p.orientation;
    const Vec3 origin = p.position + layer * p.offset + turn * ((column - 0.5 * (p.columns - 1)) * p.spread);
    auto world = [&](const Vec3& local) -> Vec3 { return origin + q * (p.scale * local); };  // not an Eigen expression: it would dangle
    const std::string prefix = p.name + "_" + std::to_string(k) + "_";
    BodyMaterial m = p.material;
    m.group = p.material.group < 0 ? k : p.material.group * 1000 + k;
    // Without self-collision each ragdoll is its own negative filter group.
    if (p.material.filterGroup < 0) m.filterGroup = p.material.filterGroup * 100000 - k;
    std::vector<int> ids;
    for (const Part& part : parts()) {
      BodyMaterial pm = m;
      pm.mass = part.mass * massScale;
      BodyState s = at(world(part.centre), q);
      s.v = p.velocity;
      ids.push_back(addBody(scene, makeDynamic(prefix + part.name, scaled(part.shape, p.scale), pm), s));
    }
    for (const JointSpec& js : joints()) {
      const Vec3 anchor = world(js.anchor);
      Joint j = makeJoint(scene, js.type, ids[static_cast<size_t>(js.a)], ids[static_cast<size_t>(js.b)], anchor, anchor,
                          q * js.axis);
      j.name = prefix + scene.model.bodies[static_cast<size_t>(j.bodyB)].name.substr(prefix.size());
      j.hasLimits = true;
      j.lower = js.lower;
      j.upper = js.upper;
      j.swing = js.swing;
      scene.model.joints.push_back(j);
    }
  }
}

}  // namespace substep

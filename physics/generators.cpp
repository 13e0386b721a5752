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

}  // namespace substep

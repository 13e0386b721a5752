#include "physics/snapshot.h"

#include "physics/constraints/joints.h"
#include "physics/world.h"

#include <algorithm>

namespace substep {

namespace {

Vec3f32 f32(const Vec3& v) { return v.cast<float>(); }

std::vector<JointSnap> jointErrors(const Model& model, const State& s) {
  std::vector<JointSnap> joints(model.joints.size());
  for (size_t k = 0; k < model.joints.size(); ++k) {
    const Joint& j = model.joints[k];
    joints[k].error = static_cast<float>(
        jointError(j, s.bodies[static_cast<size_t>(j.bodyA)].pose(), s.bodies[static_cast<size_t>(j.bodyB)].pose()));
  }
  return joints;
}

}  // namespace

double Snapshot::deepest() const {
  double d = 0;
  for (const ContactSnap& c : contacts) d = std::max(d, static_cast<double>(c.depth));
  return d;
}

double Snapshot::worstJointError() const {
  double e = 0;
  for (const JointSnap& j : joints) e = std::max(e, static_cast<double>(j.error));
  return e;
}

Snapshot takeSnapshot(const Model& model, const State& state) {
  Snapshot s;
  s.state = state;
  s.joints = jointErrors(model, state);
  return s;
}

Snapshot takeSnapshot(const World& world) {
  const State& st = world.state();
  Snapshot s = takeSnapshot(world.model(), st);
  // Points from the manifolds themselves (their anchors at the current poses, as contactGap
  // measures a ContactDef), so that a snapshot does not lean on the order of the step's rows.
  for (const Manifold& m : world.manifolds()) {
    const Pose A = st.bodies[static_cast<size_t>(m.a)].pose(), B = st.bodies[static_cast<size_t>(m.b)].pose();
    ManifoldSnap ms;
    ms.a = m.a;
    ms.b = m.b;
    ms.first = static_cast<int32_t>(s.contacts.size());
    ms.count = m.count;
    ms.friction = f32(B.rotate(m.frictionImpulse));
    ms.twist = static_cast<float>(m.twistImpulse);
    for (int k = 0; k < m.count; ++k) {
      const ManifoldPoint& p = m.points[k];
      const Vec3 pa = A.apply(p.localA), pb = B.apply(p.localB), n = B.rotate(p.localN);
      ContactSnap c;
      c.point = f32(0.5 * (pa + pb));
      c.normal = f32(n);
      c.depth = static_cast<float>(-(pa - pb).dot(n));
      c.normalImpulse = static_cast<float>(p.lambda);
      s.contacts.push_back(c);
    }
    s.manifolds.push_back(ms);
  }
  // Joint impulses: the sums of their rows' λ J̌ on body A (rows of this step, in world terms).
  const ConstraintSet& cs = world.constraints();
  for (const ConstraintSet::JointRef& r : cs.joints) {
    if (r.joint < 0 || static_cast<size_t>(r.joint) >= s.joints.size()) continue;
    const Quat qA = st.bodies[static_cast<size_t>(world.model().joints[static_cast<size_t>(r.joint)].bodyA)].q;
    Vec3 lin = Vec3::Zero(), ang = Vec3::Zero();
    for (int k = r.first; k < r.first + r.count; ++k) {
      const Row& row = cs.rows[static_cast<size_t>(k)];
      lin += row.lambda * row.lin;
      ang += row.lambda * (qA * row.angA);
    }
    s.joints[static_cast<size_t>(r.joint)].linear = f32(lin);
    s.joints[static_cast<size_t>(r.joint)].angular = f32(ang);
  }
  for (size_t i = 0; i < st.bodies.size(); ++i)
    if (world.asleep(static_cast<int>(i))) s.asleep.push_back(static_cast<int32_t>(i));
  return s;
}

}  // namespace substep

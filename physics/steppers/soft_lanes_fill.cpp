#include "physics/steppers/soft_lanes_fill.h"

namespace substep::lanes {

namespace {
void put(Doubles* to, int l, const Vec3& v) {
  for (int i = 0; i < 3; ++i) to[i].x[l] = v[i];
}
}  // namespace

void gatherManifold(const ConstraintSet& cs, size_t k, int l, ManifoldLanes& in) {
  const FrictionDef& f = cs.frictions[k];
  const Frame& A = cs.frame(f.a);
  const Frame& B = cs.frame(f.b);
  put(in.pA, l, A.p);
  put(in.pB, l, B.p);
  for (int i = 0; i < 9; ++i) {
    in.RA[i].x[l] = A.R.data()[i];
    in.RB[i].x[l] = B.R.data()[i];
  }
  const ContactDef* c = cs.manifoldContacts(k);
  in.normals[l] = f.normalCount;
  for (int q = 0; q < kMaxNormals; ++q) {
    ManifoldLanes::Point& p = in.point[q];
    const bool has = q < f.normalCount;
    put(p.localA, l, has ? c[q].localA : Vec3::Zero());
    put(p.localB, l, has ? c[q].localB : Vec3::Zero());
    put(p.n, l, has ? c[q].worldN : Vec3::Zero());
    put(p.armA, l, has ? c[q].armA : Vec3::Zero());
    put(p.armB, l, has ? c[q].armB : Vec3::Zero());
    p.lastLambda.x[l] = has ? c[q].lastLambda : 0;
  }
  put(in.n, l, f.worldN);
  put(in.armA, l, f.armA);
  put(in.armB, l, f.armB);
  put(in.lastImpulse, l, f.lastImpulse);
  in.lastTwist.x[l] = f.lastTwist;
  in.mu.x[l] = f.mu;
  in.radius.x[l] = f.radius;
}

Formulation formulation(const ConstraintSet& cs, double hSub) {
  return {cs.formulationStep(), hSub, cs.slop(), cs.speculativeContacts()};
}

}  // namespace substep::lanes

#include "physics/steppers/soft_lanes_fill.h"

namespace substep::lanes {

namespace {
void put(Doubles* to, int l, const Vec3& v) {
  for (int i = 0; i < 3; ++i) to[i].x[l] = v[i];
}
void putZero(Doubles* to, int l) {
  for (int i = 0; i < 3; ++i) to[i].x[l] = 0;
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
  const ManifoldPoint* c = cs.manifoldPoints(k);
  in.normals[l] = f.normalCount;
  for (int q = 0; q < f.normalCount; ++q) {
    ManifoldLanes::Point& p = in.point[q];
    put(p.localA, l, c[q].localA);
    put(p.localB, l, c[q].localB);
    if (f.worldFrame) {
      put(p.n, l, c[q].worldN);
      put(p.armA, l, c[q].armA);
      put(p.armB, l, c[q].armB);
    } else {
      put(in.localN[q], l, c[q].localN);
    }
    p.lastLambda.x[l] = c[q].lambda;
  }
  // Points the manifold lacks: zero (the kernel makes them zero rows whatever they hold).
  for (int q = f.normalCount; q < kMaxNormals; ++q) {
    ManifoldLanes::Point& p = in.point[q];
    for (Doubles* v : {p.localA, p.localB, p.n, p.armA, p.armB, in.localN[q]}) putZero(v, l);
    p.lastLambda.x[l] = 0;
  }
  if (f.worldFrame) {
    put(in.n, l, f.worldN);
    put(in.armA, l, f.armA);
    put(in.armB, l, f.armB);
  } else {
    put(in.frictionLocalA, l, f.localA);
    put(in.frictionLocalB, l, f.localB);
    put(in.frictionLocalN, l, f.localN);
  }
  put(in.lastImpulse, l, f.lastImpulse);
  in.lastTwist.x[l] = f.lastTwist;
  in.mu.x[l] = f.mu;
  in.radius.x[l] = f.radius;
}

void putMasses(Group& g, int l, const BodyMass& A, const BodyMass& B, bool used) {
  g.mA.x[l] = used ? A.invMass : 0;
  g.mB.x[l] = used ? B.invMass : 0;
  for (int i = 0; i < 3; ++i) {
    g.invIA[i].x[l] = used ? A.invI[i] : 0;
    g.invIB[i].x[l] = used ? B.invI[i] : 0;
  }
}

Formulation formulation(const ConstraintSet& cs, double hSub) {
  return {cs.formulationStep(), hSub, cs.slop(), cs.speculativeContacts()};
}

}  // namespace substep::lanes

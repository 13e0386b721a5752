#include "physics/constraints/contact.h"

#include "physics/constraints/parts.h"

namespace substep {

double contactGap(const ContactDef& c, const Frame& A, const Frame& B) {
  return (A.apply(c.localA) - B.apply(c.localB)).dot(c.worldFrame ? c.worldN : B.rotate(c.localN));
}

void formulateContact(const ContactDef& c, const Frame& A, const Frame& B, double h, double slop, Row& row,
                      bool jacobianOnly) {
  const Vec3 pa = A.apply(c.localA), pb = B.apply(c.localB);
  const Vec3 n = c.worldFrame ? c.worldN : B.rotate(c.localN);
  // Arms to the midpoint of pa and pb: the same J as arms to pa and pb, since the two differ
  // along n and (ω × s n)·n = 0. In the world frame, the arms the narrowphase found.
  const Vec3 m = 0.5 * (pa + pb);
  if (c.worldFrame)
    axisRow(row, c.a, c.b, A, B, c.armA, c.armB, n);
  else
    axisRow(row, c.a, c.b, A, B, m - A.p, m - B.p, n);
  if (jacobianOnly) return;
  row.bias = -((pa - pb).dot(n) + slop) / h;
  row.lo = 0;
  row.hi = kInfinity;
}

void formulateFriction(const FrictionDef& f, const Frame& A, const Frame& B, Row* rows, bool jacobianOnly) {
  const Vec3 n = f.worldFrame ? f.worldN : B.rotate(f.localN);
  // Both bodies' impulses act at one point, so friction conserves angular momentum exactly.
  const Vec3 c = 0.5 * (A.apply(f.localA) + B.apply(f.localB));
  const Vec3 armA = f.worldFrame ? f.armA : Vec3(c - A.p), armB = f.worldFrame ? f.armB : Vec3(c - B.p);
  Vec3 t1, t2;
  tangentBasis(n, t1, t2);
  axisRow(rows[0], f.a, f.b, A, B, armA, armB, t1);
  axisRow(rows[1], f.a, f.b, A, B, armA, armB, t2);
  angleRow(rows[2], f.a, f.b, A, B, n);
  for (int k = 0; k < 3; ++k) rows[k].velocityLevel = true;
  if (jacobianOnly) return;
  for (int k = 0; k < 3; ++k) {
    const double mu = k < 2 ? f.mu : f.mu * f.radius;
    rows[k].bias = 0;
    rows[k].lo = -mu;
    rows[k].hi = mu;
    rows[k].normalRow = f.firstNormal;
    rows[k].normalCount = f.normalCount;
  }
}

Vec3 frictionImpulseInB(const Quat& qB, const Row* rows) {
  return frictionImpulseInB(qB, rows[0].lambda, rows[0].lin, rows[1].lambda, rows[1].lin);
}

Vec3 frictionImpulseInB(const Quat& qB, double lambda1, const Vec3& t1, double lambda2, const Vec3& t2) {
  return qB.conjugate() * (lambda1 * t1 + lambda2 * t2);
}

void carryFrictionImpulse(const Vec3& impulseInB, const Frame& B, Row* rows) {
  const Vec3 P = B.rotate(impulseInB);
  rows[0].lambda = P.dot(rows[0].lin);
  rows[1].lambda = P.dot(rows[1].lin);
}

}  // namespace substep

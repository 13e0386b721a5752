#include "physics/constraints/contact.h"

#include "physics/constraints/parts.h"

namespace substep {

double contactGap(const ContactDef& c, const Pose& A, const Pose& B) {
  return (A.apply(c.localA) - B.apply(c.localB)).dot(B.rotate(c.localN));
}

void formulateContact(const ContactDef& c, const Pose& A, const Pose& B, double h, double slop, Row* rows,
                      bool jacobianOnly) {
  const Vec3 pa = A.apply(c.localA), pb = B.apply(c.localB);
  const Vec3 n = B.rotate(c.localN);
  // Arms to the midpoint of pa and pb: for the normal row the same J as arms to pa and pb (the
  // difference is along n), and friction impulses act at one point, so they conserve angular
  // momentum exactly.
  const Vec3 m = 0.5 * (pa + pb);
  const Vec3 rA = m - A.p, rB = m - B.p;
  Vec3 t1, t2;
  tangentBasis(n, t1, t2);
  axisRow(rows[0], c.a, c.b, A, B, rA, rB, n);
  axisRow(rows[1], c.a, c.b, A, B, rA, rB, t1);
  axisRow(rows[2], c.a, c.b, A, B, rA, rB, t2);
  if (jacobianOnly) return;
  const double C = (pa - pb).dot(n) + slop;
  rows[0].bias = -C / h;
  rows[0].lo = 0;
  rows[0].hi = kInfinity;
  for (int k = 1; k < 3; ++k) {
    rows[k].bias = 0;
    rows[k].lo = -c.mu;
    rows[k].hi = c.mu;
  }
}

}  // namespace substep

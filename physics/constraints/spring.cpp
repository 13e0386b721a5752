// Stiff spring (a rigid distance): the anchors stay restLength apart. A 'stable' constraint in
// Havok's sense, whose Jacobian depends on the coordinates: under A4/A5 it is recomputed at every
// sub-step from the stepped coordinates (the report's IV.3.2, third item).
//   d = pA - pB,  n = d/|d|
//   C = |d| - L,  Ċ = n·(ṗA - ṗB)          J̌ = (n, R_A⁻¹(rA×n), -n, -R_B⁻¹(rB×n))
//   β = -C/h,  λ unbounded
#include "physics/constraints/joints.h"
#include "physics/constraints/parts.h"

namespace substep {

void formulateSpring(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly) {
  const Vec3 rA = A.rotate(j.localAnchorA), rB = B.rotate(j.localAnchorB);
  const Vec3 d = (A.p + rA) - (B.p + rB);
  const double len = d.norm();
  const Vec3 n = len > 1e-12 ? Vec3(d / len) : Vec3::UnitX();
  axisRow(rows[0], j.bodyA, j.bodyB, A, B, rA, rB, n);
  if (jacobianOnly) return;
  rows[0].bias = -(len - j.restLength) / h;
  rows[0].lo = -kInfinity;
  rows[0].hi = kInfinity;
}

}  // namespace substep

// Fixed: the anchors coincide and B keeps its orientation relative to A.
//
// Anchors: the ball joint's three rows (ball.cpp).
// Orientation: each body carries the frame F = [axis, ref, axis × ref] (local axes that matched in
// the world when the joint was made). d = rotation vector of F_A F_Bᵀ, the turn that brings B's
// frame back onto A's. Three rows on the world axes e_i:
//   Ċ_i = e_i·(ωA - ωB),  β_i = -d_i/h       (B must turn by d relative to A)
// Both parts are unbounded: two 'stable' 3x3 blocks.
#include "physics/constraints/ball.h"
#include "physics/constraints/joints.h"
#include "physics/constraints/parts.h"

namespace substep {

namespace {

Mat3 frame(const Pose& P, const Vec3& axis, const Vec3& ref) {
  Mat3 F;
  const Vec3 a = P.rotate(axis).normalized();
  const Vec3 r = (P.rotate(ref) - a.dot(P.rotate(ref)) * a).normalized();
  F.col(0) = a;
  F.col(1) = r;
  F.col(2) = a.cross(r);
  return F;
}

}  // namespace

Vec3 fixedJointTurn(const Joint& j, const Pose& A, const Pose& B) {
  const Mat3 err = frame(A, j.localAxisA, j.localRefA) * frame(B, j.localAxisB, j.localRefB).transpose();
  return rotationVector(Quat(err));
}

void formulateFixed(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly) {
  pointRows(j, A, B, h, rows, jacobianOnly);
  const Vec3 d = fixedJointTurn(j, A, B);
  for (int i = 0; i < 3; ++i) {
    angleRow(rows[3 + i], j.bodyA, j.bodyB, A, B, Vec3::Unit(i));
    if (jacobianOnly) continue;
    rows[3 + i].bias = -d[i] / h;
    rows[3 + i].lo = -kInfinity;
    rows[3 + i].hi = kInfinity;
  }
}

}  // namespace substep

#include "physics/constraints/ball.h"

#include "physics/constraints/joints.h"
#include "physics/constraints/parts.h"

namespace substep {

Vec3 ballError(const Joint& j, const Pose& A, const Pose& B) { return A.apply(j.localAnchorA) - B.apply(j.localAnchorB); }

void pointRows(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly) {
  const Vec3 rA = A.rotate(j.localAnchorA), rB = B.rotate(j.localAnchorB);
  const Vec3 C = (A.p + rA) - (B.p + rB);
  for (int i = 0; i < 3; ++i) {
    axisRow(rows[i], j.bodyA, j.bodyB, A, B, rA, rB, Vec3::Unit(i));
    if (jacobianOnly) continue;
    rows[i].bias = -C[i] / h;
    rows[i].lo = -kInfinity;
    rows[i].hi = kInfinity;
  }
}

void formulateBall(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly) {
  pointRows(j, A, B, h, rows, jacobianOnly);
}

}  // namespace substep

// Constant-velocity motor: B turns relative to A about the axis (fixed in A) at `motorSpeed`,
// with a torque of at most motorMaxTorque (0: unbounded).
//   Ċ = aA·(ωB - ωA) = (-aA)·(ωA - ωB),   β = speed (a velocity: nothing to correct)
// The report (IV.3.1.4): A4/A5's bias update β ← β - J̌v̌ is built for position constraints;
// a motor must undo it. Rows flagged velocityTarget keep their bias in A4 and take back the
// SumVelocity term in A5 (a4/a5 steppers), and solve with κ = τ = 1 (docs/algorithms.md).
#include "physics/constraints/joints.h"
#include "physics/constraints/parts.h"

namespace substep {

void formulateMotor(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly) {
  angleMotorRow(rows[0], j.bodyA, j.bodyB, A, B, -A.rotate(j.localAxisA), j.motorSpeed, j.motorMaxTorque, h,
                jacobianOnly);
}

}  // namespace substep

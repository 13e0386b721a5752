// Hinge: the anchors coincide and the axis fixed in A stays aligned with the axis fixed in B;
// optionally the angle about it is limited and driven by a motor.
//
// Anchors: the ball joint's three rows (ball.cpp).
// Axes: aA = R_A âA, aB = R_B âB. Two rows on b = R_A r̂A (A's reference direction, across the
// axis) and c = aA × b:
//   Ċ_u = u·(ωA - ωB)                  J̌ = (0, R_A⁻¹u, 0, -R_B⁻¹u)
//   β_u = u·(aA × aB)/h                B turns by aB × aA (about b and c) to bring aB back to aA
// Angle: θ = atan2(aA·(rA × rB), rA·rB), rA, rB the reference directions; θ̇ = aA·(ωB - ωA).
//   lower limit  C = θ - lo >= 0,  Ċ = θ̇  = (-aA)·(ωA - ωB)
//   upper limit  C = hi - θ >= 0,  Ċ = -θ̇ =   aA ·(ωA - ωB)
//   motor        θ̇ = speed, |λ| <= maxTorque h
#include "physics/constraints/ball.h"
#include "physics/constraints/joints.h"
#include "physics/constraints/parts.h"

#include <cmath>

namespace substep {

double hingeAngle(const Joint& j, const Pose& A, const Pose& B) {
  const Vec3 a = A.rotate(j.localAxisA);
  const Vec3 rA = A.rotate(j.localRefA), rB = B.rotate(j.localRefB);
  return std::atan2(a.dot(rA.cross(rB)), rA.dot(rB));
}

void formulateHinge(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly) {
  pointRows(j, A, B, h, rows, jacobianOnly);
  const Vec3 aA = A.rotate(j.localAxisA), aB = B.rotate(j.localAxisB);
  // b, c across the axis, fixed in A: they turn with A, so warm-started impulses keep their
  // directions from one (sub-)step to the next (a basis computed from aA's world components
  // jumps where they cross a threshold).
  const Vec3 b = A.rotate(j.localRefA), c = aA.cross(b);
  const Vec3 e = aA.cross(aB);
  angleRow(rows[3], j.bodyA, j.bodyB, A, B, b);
  angleRow(rows[4], j.bodyA, j.bodyB, A, B, c);
  if (!jacobianOnly) {
    for (int k = 3; k < 5; ++k) {
      rows[k].bias = (k == 3 ? b : c).dot(e) / h;
      rows[k].lo = -kInfinity;
      rows[k].hi = kInfinity;
    }
  }
  int next = 5;
  const double theta = hingeAngle(j, A, B);
  if (j.hasLimits) {
    angleLimitRow(rows[next++], j.bodyA, j.bodyB, A, B, -aA, theta - j.lower, h, jacobianOnly);
    angleLimitRow(rows[next++], j.bodyA, j.bodyB, A, B, aA, j.upper - theta, h, jacobianOnly);
  }
  if (j.hasMotor) angleMotorRow(rows[next], j.bodyA, j.bodyB, A, B, -aA, j.motorSpeed, j.motorMaxTorque, h, jacobianOnly);
}

}  // namespace substep

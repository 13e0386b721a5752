// Cone-twist (ragdoll shoulders, hips, neck, spine): the anchors coincide, the twist axis of B
// stays within a cone about the twist axis of A, and the twist about it is limited.
//
// Anchors: the ball joint's three rows (ball.cpp).
// Swing: θs = angle(aA, aB), u = (aA × aB)/|aA × aB|, B turning about u opens it:
//   C = swing - θs >= 0,   Ċ = -θ̇s = u·(ωA - ωB)
// Twist: about t = (aA + aB)/|aA + aB|, between the reference directions projected across t:
//   θt = atan2(t·(pA × pB), pA·pB),  θ̇t = t·(ωB - ωA)
//   lower C = θt - lo >= 0 on -t,  upper C = hi - θt >= 0 on t
// All three are inequalities: bounded rows, not a 'stable' block.
#include "physics/constraints/ball.h"
#include "physics/constraints/joints.h"
#include "physics/constraints/parts.h"

#include <algorithm>
#include <cmath>

namespace substep {

namespace {

Vec3 twistAxis(const Joint& j, const Pose& A, const Pose& B) {
  const Vec3 s = A.rotate(j.localAxisA) + B.rotate(j.localAxisB);
  const double n = s.norm();
  return n > 1e-9 ? Vec3(s / n) : A.rotate(j.localAxisA);  // opposite axes: the swing limit is broken anyway
}

}  // namespace

double swingAngle(const Joint& j, const Pose& A, const Pose& B) {
  const Vec3 aA = A.rotate(j.localAxisA), aB = B.rotate(j.localAxisB);
  return std::atan2(aA.cross(aB).norm(), aA.dot(aB));
}

double twistAngle(const Joint& j, const Pose& A, const Pose& B) {
  const Vec3 t = twistAxis(j, A, B);
  Vec3 pA = A.rotate(j.localRefA), pB = B.rotate(j.localRefB);
  pA -= pA.dot(t) * t;
  pB -= pB.dot(t) * t;
  return std::atan2(t.dot(pA.cross(pB)), pA.dot(pB));
}

void formulateConeTwist(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly) {
  pointRows(j, A, B, h, rows, jacobianOnly);
  const Vec3 aA = A.rotate(j.localAxisA), aB = B.rotate(j.localAxisB);
  Vec3 u = aA.cross(aB);
  if (u.norm() > 1e-9) {
    u.normalize();
  } else {
    Vec3 c;
    tangentBasis(aA, u, c);  // aligned: any direction across the axis (the row is far from its limit)
  }
  angleLimitRow(rows[3], j.bodyA, j.bodyB, A, B, u, j.swing - swingAngle(j, A, B), h, jacobianOnly);
  if (j.hasLimits) {
    const Vec3 t = twistAxis(j, A, B);
    const double theta = twistAngle(j, A, B);
    angleLimitRow(rows[4], j.bodyA, j.bodyB, A, B, -t, theta - j.lower, h, jacobianOnly);
    angleLimitRow(rows[5], j.bodyA, j.bodyB, A, B, t, j.upper - theta, h, jacobianOnly);
  }
}

}  // namespace substep

// Reusable constraint parts, as Jolt builds its joints from them: every constraint in
// physics/constraints/ is a few of these rows.
#pragma once

#include "physics/constraints/row.h"
#include "physics/math.h"

namespace substep {

// Axis part: the relative velocity of two points along a world axis u.
//   C = (pA - pB)·u,  Ċ = u·vA + (rA×u)·ωA - u·vB - (rB×u)·ωB
//   J̌ = (u, R_A⁻¹(rA×u), -u, -R_B⁻¹(rB×u))     (report III.1: rotational parts k -> R⁻¹k)
// rA = pA - xA and rB = pB - xB are the world arms σ of the report's IV.3.1.1.
// P: a Pose or a Frame (anything with unrotate).
template <class P>
inline void axisRow(Row& r, int a, int b, const P& A, const P& B, const Vec3& rA, const Vec3& rB, const Vec3& u) {
  r.a = a;
  r.b = b;
  r.lin = u;  // -u on B
  r.angA = A.unrotate(rA.cross(u));
  r.angB = -B.unrotate(rB.cross(u));
}

// Angle part: the relative angular velocity about a world axis u.
//   Ċ = u·(ωA - ωB),  J̌ = (0, R_A⁻¹u, 0, -R_B⁻¹u)
template <class P>
inline void angleRow(Row& r, int a, int b, const P& A, const P& B, const Vec3& u) {
  r.a = a;
  r.b = b;
  r.lin.setZero();
  r.angA = A.unrotate(u);
  r.angB = -B.unrotate(u);
}

// An angular inequality C >= 0 whose rate is Ċ = u·(ωA - ωB): a joint limit. While C > 0 the
// bias -C/h lets the bodies close the remaining angle in this step and no further.
inline void angleLimitRow(Row& r, int a, int b, const Pose& A, const Pose& B, const Vec3& u, double C, double h,
                          bool jacobianOnly) {
  angleRow(r, a, b, A, B, u);
  if (jacobianOnly) return;
  r.bias = -C / h;
  r.lo = 0;
  r.hi = kInfinity;
}

// A motor: u·(ωA - ωB) driven to `speed`, with the impulse of one step bounded by maxTorque h
// (unbounded for maxTorque 0). Its bias is a velocity, not a position correction (IV.3.1.4).
inline void angleMotorRow(Row& r, int a, int b, const Pose& A, const Pose& B, const Vec3& u, double speed,
                          double maxTorque, double h, bool jacobianOnly) {
  angleRow(r, a, b, A, B, u);
  r.velocityLevel = true;
  r.velocityTarget = true;
  if (jacobianOnly) return;
  r.bias = speed;
  r.lo = maxTorque > 0 ? -maxTorque * h : -kInfinity;
  r.hi = maxTorque > 0 ? maxTorque * h : kInfinity;
}

}  // namespace substep

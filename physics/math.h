// Small math vocabulary shared by the whole physics library.
// Units are SI; the world is right-handed with Y up. Quaternions are printed [w, x, y, z].
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>

namespace substep {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Quat = Eigen::Quaterniond;

// A rigid transform: x_world = R(q) x_local + p.
struct Pose {
  Vec3 p = Vec3::Zero();
  Quat q = Quat::Identity();

  Vec3 apply(const Vec3& local) const { return q * local + p; }
  Vec3 rotate(const Vec3& local) const { return q * local; }
  Vec3 unrotate(const Vec3& world) const { return q.conjugate() * world; }
};

// A Pose with its rotation as a matrix: for formulation, which rotates every contact point's
// arms, normal and Jacobian five times; R v costs 15 flops where q v costs about 30.
struct Frame {
  Vec3 p = Vec3::Zero();
  Mat3 R = Mat3::Identity();

  Frame() = default;
  Frame(const Pose& pose) : p(pose.p), R(pose.q.toRotationMatrix()) {}  // NOLINT: implicit on purpose
  Vec3 apply(const Vec3& local) const { return R * local + p; }
  Vec3 rotate(const Vec3& local) const { return R * local; }
  // R^T u written out, summed left to right as Eigen's product is (the same numbers): Eigen's SSE2
  // form stored u's scalars and loaded them back as a pair, a store-forwarding stall that was a
  // third of formulating a contact point (docs/benchmarks.md).
  Vec3 unrotate(const Vec3& u) const {
    return Vec3(R(0, 0) * u.x() + R(1, 0) * u.y() + R(2, 0) * u.z(), R(0, 1) * u.x() + R(1, 1) * u.y() + R(2, 1) * u.z(),
                R(0, 2) * u.x() + R(1, 2) * u.y() + R(2, 2) * u.z());
  }
};

// The report's R_q(a): the unit quaternion of the rotation vector a (axis a/|a|, angle |a|).
// Exact exponential map; near zero the series keeps it smooth and unit length.
inline Quat Rq(const Vec3& a) {
  const double theta = a.norm();
  const double half = 0.5 * theta;
  double s, c;  // sin(theta/2)/theta, cos(theta/2)
  if (theta < 1e-6) {
    // cos's series to x²: the x⁴ term is below 1e-26, and this is glibc's cos to the bit
    // (checked on 78 million angles below 5e-7); no call where a body barely turns.
    s = 0.5 - theta * theta / 48.0;
    c = 1.0 - 0.5 * (half * half);
  } else {
    // One call for both (glibc's sincos gives sin's and cos's bits: the trajectory table holds).
    double sinHalf;
    ::sincos(half, &sinHalf, &c);
    s = sinHalf / theta;
  }
  return Quat(c, s * a.x(), s * a.y(), s * a.z());
}

// The inverse of Rq: rotation vector of a unit quaternion (angle in [0, pi]).
inline Vec3 rotationVector(const Quat& qIn) {
  Quat q = qIn;
  if (q.w() < 0) q.coeffs() = -q.coeffs();  // q and -q are the same rotation
  const Vec3 v = q.vec();
  const double s = v.norm();
  if (s < 1e-12) return 2.0 * v;
  const double angle = 2.0 * std::atan2(s, q.w());
  return v * (angle / s);
}

// Angle of the rotation that takes a to b (both unit), in radians.
inline double angleBetween(const Quat& a, const Quat& b) {
  return rotationVector(a.conjugate() * b).norm();
}

inline Mat3 skew(const Vec3& a) {
  Mat3 m;
  m << 0, -a.z(), a.y(), a.z(), 0, -a.x(), -a.y(), a.x(), 0;
  return m;
}

// Two unit vectors orthogonal to n and to each other (friction directions).
inline void tangentBasis(const Vec3& n, Vec3& t1, Vec3& t2) {
  // Eigen's normalized() of (x, y, z) written out, the same numbers ((x² + y²) + z², then x/|v|
  // ...): a Vec3 built from scalars and then normalised went through memory as two scalar stores
  // and a pair load, a store-forwarding stall (docs/benchmarks.md).
  const auto unit = [](double x, double y, double z) {
    const double s = (x * x + y * y) + z * z;
    if (!(s > 0)) return Vec3(x, y, z);
    const double r = std::sqrt(s);
    return Vec3(x / r, y / r, z / r);
  };
  // Pick the axis least aligned with n so the cross product is well conditioned.
  if (std::abs(n.x()) < 0.57735) {
    t1 = unit(0, n.z(), -n.y());  // n x e_x
  } else {
    t1 = unit(n.z(), 0, -n.x());  // e_y x n
  }
  t2 = n.cross(t1);
}

inline bool allFinite(const Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }

}  // namespace substep

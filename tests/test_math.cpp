// The report's derivations (sections III and V) as property tests on random states.
#include "physics/constraints/parts.h"
#include "physics/math.h"

#include <gtest/gtest.h>

#include <random>

using namespace substep;

namespace {

struct Rng {
  std::mt19937_64 g{12345};
  double uni(double a, double b) { return std::uniform_real_distribution<double>(a, b)(g); }
  Vec3 vec(double s = 1) { return Vec3(uni(-s, s), uni(-s, s), uni(-s, s)); }
  Quat quat() { return Quat(Eigen::AngleAxisd(uni(0, M_PI), vec().normalized())); }
  Vec3 unit() { return vec().normalized(); }
};

}  // namespace

// III.1: J v = J̌ v̌ when the rotational parts k become R⁻¹k and ω becomes v̌ = R⁻¹ω.
TEST(Derivations, LocalJacobianGivesTheSameConstraintVelocity) {
  Rng r;
  for (int t = 0; t < 1000; ++t) {
    const Pose A{r.vec(5), r.quat()}, B{r.vec(5), r.quat()};
    const Vec3 rA = r.vec(), rB = r.vec(), n = r.unit();
    const Vec3 vA = r.vec(3), vB = r.vec(3), wA = r.vec(3), wB = r.vec(3);  // world angular velocities
    // World-frame Jacobian of IV.3.1.1: (n, σa×n, -n, -σb×n).
    const double Jv = n.dot(vA) + rA.cross(n).dot(wA) - n.dot(vB) - rB.cross(n).dot(wB);
    Row row;
    axisRow(row, 0, 1, A, B, rA, rB, n);
    const Vec3 v[2] = {vA, vB};
    const Vec3 wLocal[2] = {A.unrotate(wA), B.unrotate(wB)};
    EXPECT_NEAR(rowVelocity(row, v, wLocal), Jv, 1e-12 * (1 + std::abs(Jv)));
    // And the angle part: u·(ωA - ωB).
    angleRow(row, 0, 1, A, B, n);
    EXPECT_NEAR(rowVelocity(row, v, wLocal), n.dot(wA - wB), 1e-12);
  }
}

// III.2: the local inverse mass is the change of basis R⁻¹ (R M̌⁻¹ R⁻¹) R of the world one, i.e.
// the constant principal diagonal: an impulse through J̌ gives the same velocity change as the
// world formulation through J with I_world⁻¹ = R diag(1/I) Rᵀ.
TEST(Derivations, LocalInverseMassIsTheChangeOfBasis) {
  Rng r;
  for (int t = 0; t < 1000; ++t) {
    const Pose A{r.vec(5), r.quat()}, B{Vec3::Zero(), Quat::Identity()};
    const Vec3 I(r.uni(0.1, 5), r.uni(0.1, 5), r.uni(0.1, 5));
    const Vec3 invI = I.cwiseInverse();
    const Mat3 R = A.q.toRotationMatrix();
    const Mat3 invIWorld = R * invI.asDiagonal() * R.transpose();
    const Vec3 rA = r.vec(), n = r.unit();
    const double lambda = r.uni(-2, 2);
    const Vec3 dwWorld = invIWorld * rA.cross(n) * lambda;
    Row row;
    axisRow(row, 0, 1, A, B, rA, Vec3::Zero(), n);
    finishRow(row, BodyMass{1.0, invI}, BodyMass{}, 1.0);
    const Vec3 dwLocal = row.mAngA * lambda;  // M̌⁻¹J̌ᵀλ
    EXPECT_LT((R * dwLocal - dwWorld).norm(), 1e-12 * (1 + dwWorld.norm()));
    // The report's boxed change of basis: R_E→j (R M⁻¹ Rᵀ) R_j→E is diagonal and constant.
    const Mat3 back = R.transpose() * invIWorld * R;
    EXPECT_LT((back - Mat3(invI.asDiagonal())).norm(), 1e-12 * invI.norm());
    // Effective mass agrees with the world one.
    const double kWorld = 1.0 + rA.cross(n).dot(invIWorld * rA.cross(n));
    EXPECT_NEAR(1.0 / row.effMass, kWorld, 1e-12 * kWorld);
  }
}

TEST(Rotations, RqIsTheExactExponential) {
  Rng r;
  for (int t = 0; t < 200; ++t) {
    const Vec3 a = r.vec(1.8);  // |a| < π, where the rotation vector is unique
    const Quat q = Rq(a);
    EXPECT_NEAR(q.norm(), 1.0, 1e-15);
    const Eigen::AngleAxisd aa(a.norm(), a.normalized());
    EXPECT_LT((q.toRotationMatrix() - aa.toRotationMatrix()).norm(), 1e-14);
    EXPECT_LT((rotationVector(q) - a).norm(), 1e-12) << a.transpose();
  }
  EXPECT_LT((Rq(Vec3(1e-9, 0, 0)).vec() - Vec3(5e-10, 0, 0)).norm(), 1e-20);
}

// Section V: for small rotations composition commutes and adds to first order. The error of
// Rq(a)∘Rq(b) against Rq(a+b) (and against Rq(b)∘Rq(a)) is second order: halving both angles
// quarters it.
TEST(Rotations, SmallRotationsCommuteAndAddToFirstOrder) {
  Rng r;
  for (int t = 0; t < 100; ++t) {
    const Vec3 da = r.unit(), db = r.unit();
    if (da.cross(db).norm() < 0.2) continue;  // parallel axes commute exactly
    double prevAdd = 0, prevComm = 0;
    for (int k = 0; k < 8; ++k) {
      const double s = 0.2 * std::pow(0.5, k);
      const Quat ab = Rq(s * da) * Rq(s * db);
      const double addErr = angleBetween(ab, Rq(s * (da + db)));
      const double commErr = angleBetween(ab, Rq(s * db) * Rq(s * da));
      EXPECT_GT(addErr, 0.0);
      if (k > 0) {
        EXPECT_NEAR(prevAdd / addErr, 4.0, 0.1) << "s=" << s;
        EXPECT_NEAR(prevComm / commErr, 4.0, 0.1) << "s=" << s;
      }
      // The leading term is half the commutator: |a × b| / 2 (and |a × b| for the swap).
      EXPECT_NEAR(addErr, 0.5 * s * s * da.cross(db).norm(), 0.5 * s * s * 0.25);
      prevAdd = addErr;
      prevComm = commErr;
    }
  }
}

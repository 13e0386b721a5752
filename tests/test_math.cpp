// The report's derivations (sections III and V) as property tests on random states.
#include "physics/constraints/parts.h"
#include "physics/mass.h"
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

// III.2: the local inverse mass is the change of basis ʲM̌⁻¹ = R⁻¹ (ᴱM⁻¹) R of the world one. The
// world inertia is taken from the body as it stands in the world, independently of the code's
// local one: the box as a mesh with its vertices at their world positions, integrated
// (meshMassProperties). Then (a) an impulse through the row's J̌ (M̌⁻¹J̌ᵀλ, from the body's principal
// moments) gives the angular velocity change the world formulation gives through J and that world
// inertia, and (b) the change of basis of the world inverse inertia is the constant diagonal the
// body keeps (Body::invInertia from setMassFromMass), whatever the orientation.
TEST(Derivations, LocalInverseMassIsTheChangeOfBasis) {
  Rng r;
  for (int t = 0; t < 200; ++t) {
    const Pose A{r.vec(5), r.quat()}, B{Vec3::Zero(), Quat::Identity()};
    const Vec3 e(r.uni(0.1, 1), r.uni(0.1, 1), r.uni(0.1, 1));  // half extents [m]
    const double mass = r.uni(0.5, 20);
    Body body;
    body.shape.type = ShapeType::Box;
    body.shape.halfExtents = e;
    setMassFromMass(body, mass);
    Mesh world;  // the box at A: 8 vertices, 12 outward triangles
    for (int i = 0; i < 8; ++i)
      world.vertices.push_back(A.apply(Vec3((i & 1 ? 1 : -1) * e.x(), (i & 2 ? 1 : -1) * e.y(), (i & 4 ? 1 : -1) * e.z())));
    world.triangles = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 4, 6}, {0, 6, 2},
                       {1, 3, 7}, {1, 7, 5}, {0, 1, 5}, {0, 5, 4}, {2, 6, 7}, {2, 7, 3}};
    const MassProperties mp = meshMassProperties(world, mass / (8 * e.prod()));
    ASSERT_NEAR(mp.mass, mass, 1e-12 * mass);
    const Mat3 invIWorld = mp.inertia.inverse();  // ᴱM⁻¹, rotational
    const Mat3 R = A.q.toRotationMatrix();
    const double scale = invIWorld.norm();
    // (a) the row's velocity change against the world's.
    const Vec3 rA = r.vec(), n = r.unit();
    const double lambda = r.uni(-2, 2);
    const Vec3 dwWorld = invIWorld * rA.cross(n) * lambda;
    Row row;
    axisRow(row, 0, 1, A, B, rA, Vec3::Zero(), n);
    finishRow(row, BodyMass{body.invMass, body.invInertia}, BodyMass{}, 1.0);
    const Vec3 dwLocal = row.mAngA * lambda;  // M̌⁻¹J̌ᵀλ, body frame
    EXPECT_LT((R * dwLocal - dwWorld).norm(), 1e-10 * (1 + dwWorld.norm()));
    // (b) R⁻¹ (ᴱM⁻¹) R is the body's diagonal M̌⁻¹.
    const Mat3 local = R.transpose() * invIWorld * R;
    EXPECT_LT((local - Mat3(body.invInertia.asDiagonal())).norm(), 1e-10 * scale) << local;
    // Effective mass agrees with the world one.
    const double kWorld = body.invMass + rA.cross(n).dot(invIWorld * rA.cross(n));
    EXPECT_NEAR(1.0 / row.effMass, kWorld, 1e-10 * kWorld);
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

// Below 1e-6 rad Rq takes cos(θ/2) from its series instead of calling cos (a settled body turns
// less than that a sub-step): the same bits as std::cos, so no trajectory moves.
TEST(Rotations, RqNearZeroHasTheLibrarysCosineToTheBit) {
  std::mt19937_64 r(7);
  std::uniform_real_distribution<double> mantissa(1, 2);
  int checked = 0;
  for (int e = -50; e <= -20; ++e)
    for (int k = 0; k < 2000; ++k) {
      const double theta = std::ldexp(mantissa(r), e);
      if (theta >= 1e-6) continue;
      ASSERT_EQ(Rq(Vec3(theta, 0, 0)).w(), std::cos(0.5 * theta)) << theta;
      ++checked;
    }
  EXPECT_GT(checked, 50000);
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

// Mass properties against closed forms and independent numerical integration.
#include "physics/mass.h"
#include "physics/mesh_loader.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>

using namespace substep;

namespace {

constexpr double kPi = 3.14159265358979323846;

Shape sphere(double r) {
  Shape s;
  s.type = ShapeType::Sphere;
  s.radius = r;
  return s;
}
Shape box(const Vec3& e) {
  Shape s;
  s.type = ShapeType::Box;
  s.halfExtents = e;
  return s;
}
Shape capsule(double r, double h) {
  Shape s;
  s.type = ShapeType::Capsule;
  s.radius = r;
  s.halfHeight = h;
  return s;
}
Shape cylinder(double r, double h) {
  Shape s = capsule(r, h);
  s.type = ShapeType::Cylinder;
  return s;
}

// A box as a closed triangle mesh (8 vertices, 12 triangles, outward), transformed by `pose`.
Mesh boxMesh(const Vec3& e, const Pose& pose = Pose()) {
  Mesh m;
  for (int i = 0; i < 8; ++i)
    m.vertices.push_back(pose.apply(Vec3((i & 1 ? 1 : -1) * e.x(), (i & 2 ? 1 : -1) * e.y(), (i & 4 ? 1 : -1) * e.z())));
  // Two triangles per face, counter-clockwise seen from outside.
  m.triangles = {{0, 2, 3}, {0, 3, 1},   // -z
                 {4, 5, 7}, {4, 7, 6},   // +z
                 {0, 4, 6}, {0, 6, 2},   // -x
                 {1, 3, 7}, {1, 7, 5},   // +x
                 {0, 1, 5}, {0, 5, 4},   // -y
                 {2, 6, 7}, {2, 7, 3}};  // +y
  return m;
}

void expectMatNear(const Mat3& a, const Mat3& b, double tol) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(a(i, j), b(i, j), tol) << "entry (" << i << ", " << j << ")";
}

void expectDiag(const Mat3& I, const Vec3& d, double tol) {
  expectMatNear(I, Mat3(d.asDiagonal()), tol);
}

// Composite Simpson on [a, b] with n (even) intervals.
double simpson(const std::function<double(double)>& f, double a, double b, int n) {
  const double h = (b - a) / n;
  double s = f(a) + f(b);
  for (int i = 1; i < n; ++i) s += f(a + i * h) * (i % 2 ? 4 : 2);
  return s * h / 3;
}

// A solid of revolution about Y given by its radius profile a(y): integrate thin disks.
// A disk of radius a at height y, mass dm: axial moment dm a²/2, transverse dm (a²/4 + y²).
struct Revolved {
  double mass, transverse, axial;
};
Revolved integrateRevolved(const std::function<double(double)>& a, const std::vector<double>& breaks, double rho) {
  Revolved r{0, 0, 0};
  for (size_t k = 0; k + 1 < breaks.size(); ++k) {
    const double y0 = breaks[k], y1 = breaks[k + 1];
    const int n = 20000;
    r.mass += simpson([&](double y) { return rho * kPi * a(y) * a(y); }, y0, y1, n);
    r.axial += simpson([&](double y) { const double s = a(y) * a(y); return rho * kPi * s * s / 2; }, y0, y1, n);
    r.transverse += simpson([&](double y) { const double s = a(y) * a(y); return rho * kPi * s * (s / 4 + y * y); }, y0,
                            y1, n);
  }
  return r;
}

}  // namespace

TEST(Mass, Sphere) {
  const double r = 0.7, rho = 3;
  const MassProperties mp = shapeMassProperties(sphere(r), rho);
  const double m = rho * 4.0 / 3.0 * kPi * r * r * r;
  EXPECT_NEAR(mp.mass, m, 1e-12);
  EXPECT_NEAR(mp.com.norm(), 0, 1e-15);
  expectDiag(mp.inertia, Vec3::Constant(0.4 * m * r * r), 1e-12);
}

TEST(Mass, Box) {
  const Vec3 e(0.5, 1.0, 1.5);
  const MassProperties mp = shapeMassProperties(box(e), 2.0);
  EXPECT_NEAR(mp.mass, 2.0 * 1 * 2 * 3, 1e-12);
  // I = m/12 (b² + c²) with full side lengths 1, 2, 3.
  expectDiag(mp.inertia, Vec3(12.0 / 12 * (4 + 9), 12.0 / 12 * (1 + 9), 12.0 / 12 * (1 + 4)), 1e-12);
}

TEST(Mass, CylinderAlongY) {
  const double r = 0.3, h = 0.8, rho = 1000;
  const MassProperties mp = shapeMassProperties(cylinder(r, h), rho);
  const double m = rho * kPi * r * r * 2 * h;
  EXPECT_NEAR(mp.mass, m, 1e-9);
  const double L = 2 * h;
  expectDiag(mp.inertia, Vec3(m * (3 * r * r + L * L) / 12, m * r * r / 2, m * (3 * r * r + L * L) / 12), 1e-9);

  // The same by slicing into disks.
  const Revolved n = integrateRevolved([&](double) { return r; }, {-h, h}, rho);
  EXPECT_NEAR(mp.inertia(0, 0), n.transverse, 1e-9 * n.transverse);
  EXPECT_NEAR(mp.inertia(1, 1), n.axial, 1e-9 * n.axial);
}

TEST(Mass, CapsuleAgainstSlicedIntegration) {
  const double rho = 900;
  for (const auto& rh : {std::pair{0.5, 0.6}, std::pair{0.25, 0.35}, std::pair{0.4, 0.05}}) {
    const double r = rh.first, h = rh.second;  // not a structured binding: the lambda captures them
    const MassProperties mp = shapeMassProperties(capsule(r, h), rho);
    // Profile: cylinder of radius r for |y| <= h, hemispheres beyond.
    const auto profile = [&](double y) {
      const double d = std::max(std::abs(y) - h, 0.0);
      return std::sqrt(std::max(r * r - d * d, 0.0));
    };
    const Revolved n = integrateRevolved(profile, {-h - r, -h, h, h + r}, rho);
    EXPECT_NEAR(mp.mass, n.mass, 1e-7 * n.mass);
    EXPECT_NEAR(mp.inertia(0, 0), n.transverse, 1e-7 * n.transverse) << "r " << r << " h " << h;
    EXPECT_NEAR(mp.inertia(2, 2), n.transverse, 1e-7 * n.transverse);
    EXPECT_NEAR(mp.inertia(1, 1), n.axial, 1e-7 * n.axial);
    EXPECT_NEAR(mp.com.norm(), 0, 1e-15);

    // The check can tell the parallel-axis term apart: treating each hemisphere as half a sphere
    // centred at the segment end (d = h, no 3r/8 shift) is far off.
    const double mc = rho * kPi * r * r * 2 * h, ms = rho * 4.0 / 3.0 * kPi * r * r * r;
    const double naive = mc * (3 * r * r + 4 * h * h) / 12 + ms * (0.4 * r * r + h * h);
    EXPECT_GT(std::abs(naive - n.transverse), 1e-4 * n.transverse);
  }
}

TEST(Mass, BoxMeshMatchesBox) {
  const Vec3 e(0.3, 0.5, 0.9);
  const Mesh m = boxMesh(e);
  const MassProperties mesh = meshMassProperties(m, 750);
  const MassProperties ref = shapeMassProperties(box(e), 750);
  EXPECT_NEAR(mesh.mass, ref.mass, 1e-10);
  EXPECT_NEAR(mesh.com.norm(), 0, 1e-14);
  expectMatNear(mesh.inertia, ref.inertia, 1e-10);
  EXPECT_NEAR(meshVolume(m), 8 * e.prod(), 1e-14);

  Shape s;
  s.type = ShapeType::ConvexMesh;
  s.mesh = std::make_shared<const Mesh>(m);
  EXPECT_NEAR(shapeMassProperties(s, 750).mass, ref.mass, 1e-10);
}

TEST(Mass, InwardMeshHasNegativeVolume) {
  Mesh m = boxMesh(Vec3(1, 1, 1));
  for (auto& t : m.triangles) std::swap(t[1], t[2]);
  EXPECT_NEAR(meshVolume(m), -8, 1e-12);
  EXPECT_THROW(toPrincipalFrame(m), std::invalid_argument);
}

TEST(Mass, RotatedOffsetBoxMeshIsDiagonalisedBack) {
  const Vec3 e(0.3, 0.5, 0.9);
  Pose place;
  place.p = Vec3(3.0, -2.0, 7.5);
  place.q = Quat(Eigen::AngleAxisd(0.7, Vec3(1, 2, -0.5).normalized()));
  Mesh m = boxMesh(e, place);
  const Mesh original = m;

  // In the file frame: COM at the offset, inertia R diag Rᵀ.
  const MassProperties before = meshMassProperties(m, 1000);
  const MassProperties ref = shapeMassProperties(box(e), 1000);
  const Mat3 R = place.q.toRotationMatrix();
  EXPECT_NEAR((before.com - place.p).norm(), 0, 1e-12);
  expectMatNear(before.inertia, R * ref.inertia * R.transpose(), 1e-9);

  const Pose principal = toPrincipalFrame(m);
  EXPECT_NEAR((principal.p - place.p).norm(), 0, 1e-12);
  EXPECT_NEAR(principal.q.norm(), 1, 1e-12);
  EXPECT_NEAR(principal.q.toRotationMatrix().determinant(), 1, 1e-12);  // right-handed

  // Principal frame: COM at the origin, inertia diagonal with the box's moments.
  const MassProperties after = meshMassProperties(m, 1000);
  EXPECT_NEAR(after.com.norm(), 0, 1e-12);
  Vec3 moments = after.inertia.diagonal();
  Vec3 expected = ref.inertia.diagonal();
  std::sort(moments.data(), moments.data() + 3);
  std::sort(expected.data(), expected.data() + 3);
  EXPECT_NEAR((moments - expected).norm(), 0, 1e-9);
  EXPECT_NEAR(after.inertia(0, 1), 0, 1e-9);
  EXPECT_NEAR(after.inertia(0, 2), 0, 1e-9);
  EXPECT_NEAR(after.inertia(1, 2), 0, 1e-9);

  // The box's axes again: each vertex coordinate is ± a half extent.
  for (const Vec3& v : m.vertices) {
    Vec3 a = v.cwiseAbs();
    std::sort(a.data(), a.data() + 3);
    EXPECT_NEAR((a - Vec3(0.3, 0.5, 0.9)).norm(), 0, 1e-9);
  }
  // The returned pose takes the new vertices back to the file's.
  for (size_t i = 0; i < m.vertices.size(); ++i)
    EXPECT_NEAR((principal.apply(m.vertices[i]) - original.vertices[i]).norm(), 0, 1e-12);

  // And the body gets those moments.
  Body b;
  b.shape.type = ShapeType::ConvexMesh;
  b.shape.mesh = std::make_shared<const Mesh>(m);
  setMassFromDensity(b, 1000);
  EXPECT_NEAR(b.mass, ref.mass, 1e-9);
  Vec3 got = b.inertia;
  std::sort(got.data(), got.data() + 3);
  EXPECT_NEAR((got - expected).norm(), 0, 1e-9);
}

TEST(Mass, PrincipalAxesKeptWhenAlreadyDiagonal) {
  Pose place;
  place.p = Vec3(0, 0.4, -1);
  Mesh m = boxMesh(Vec3(0.9, 0.5, 0.3), place);  // moments out of order on purpose
  const Pose principal = toPrincipalFrame(m);
  EXPECT_NEAR((principal.p - place.p).norm(), 0, 1e-12);
  EXPECT_NEAR(angleBetween(principal.q, Quat::Identity()), 0, 1e-12);
  EXPECT_NEAR(m.vertices[7].x(), 0.9, 1e-12);
}

TEST(Mass, NonPrincipalMeshIsRejected) {
  Pose place;
  place.q = Quat(Eigen::AngleAxisd(0.5, Vec3::UnitZ()));
  Body b;
  b.shape.type = ShapeType::ConvexMesh;
  b.shape.mesh = std::make_shared<const Mesh>(boxMesh(Vec3(0.3, 0.5, 0.9), place));
  EXPECT_THROW(setMassFromDensity(b, 1000), std::invalid_argument);
  place.q = Quat::Identity();
  place.p = Vec3(1, 0, 0);
  b.shape.mesh = std::make_shared<const Mesh>(boxMesh(Vec3(0.3, 0.5, 0.9), place));
  EXPECT_THROW(setMassFromDensity(b, 1000), std::invalid_argument);
}

TEST(Mass, GemAssetVolumeAndFrame) {
  // The gem is a prism over a convex hexagon with a planar slanted top y = 0.45 + 0.25x + 0.1z:
  // its volume is the base area times the height over the base's centroid.
  Mesh m = loadMesh(std::string(SUBSTEP_SOURCE_DIR) + "/assets/meshes/gem.obj");
  ASSERT_EQ(m.vertices.size(), 12u);
  ASSERT_EQ(m.triangles.size(), 20u);
  std::vector<Vec3> base;
  for (const Vec3& v : m.vertices)
    if (std::abs(v.y()) < 1e-9) base.push_back(v);
  ASSERT_EQ(base.size(), 6u);
  Vec3 c0 = Vec3::Zero();
  for (const Vec3& v : base) c0 += v / 6.0;
  std::sort(base.begin(), base.end(), [&](const Vec3& a, const Vec3& b) {
    return std::atan2(a.z() - c0.z(), a.x() - c0.x()) < std::atan2(b.z() - c0.z(), b.x() - c0.x());
  });
  double area = 0;
  Vec3 centroid = Vec3::Zero();
  for (int i = 0; i < 6; ++i) {
    const Vec3& p = base[i];
    const Vec3& q = base[(i + 1) % 6];
    const double cr = p.x() * q.z() - q.x() * p.z();  // shoelace in the xz plane
    area += cr / 2;
    centroid += (p + q) * cr / 6;
  }
  centroid /= area;
  const double volume = area * (0.45 + 0.25 * centroid.x() + 0.10 * centroid.z());
  EXPECT_NEAR(meshVolume(m), volume, 1e-5);  // the OBJ stores 6 decimals

  const Mesh original = m;
  const Pose principal = toPrincipalFrame(m);
  EXPECT_GT(principal.p.y(), 0.1);  // the file origin is on the base, below the centre of mass
  EXPECT_GT(angleBetween(principal.q, Quat::Identity()), 1e-3);  // the slant tilts the axes
  const MassProperties after = meshMassProperties(m, 1);
  EXPECT_NEAR(after.com.norm(), 0, 1e-12);
  EXPECT_NEAR(std::abs(after.inertia(0, 1)) + std::abs(after.inertia(0, 2)) + std::abs(after.inertia(1, 2)), 0, 1e-12);
  for (size_t i = 0; i < m.vertices.size(); ++i)
    EXPECT_NEAR((principal.apply(m.vertices[i]) - original.vertices[i]).norm(), 0, 1e-12);
}

TEST(Mass, SetMassFromMassAndDensity) {
  Body b;
  b.shape = box(Vec3(0.5, 0.25, 1));
  setMassFromMass(b, 2.0);
  EXPECT_EQ(b.mass, 2.0);
  EXPECT_EQ(b.invMass, 0.5);
  const Vec3 I = Vec3(0.25 * 0.25 + 1, 0.25 + 1, 0.25 + 0.25 * 0.25) * (2.0 / 3.0);
  EXPECT_NEAR((b.inertia - I).norm(), 0, 1e-12);
  EXPECT_NEAR((b.invInertia - I.cwiseInverse()).norm(), 0, 1e-9);

  setMassFromDensity(b, 100);
  EXPECT_NEAR(b.mass, 100.0, 1e-12);  // volume 1 m^3
  EXPECT_NEAR(b.invMass, 0.01, 1e-14);

  b.isStatic = true;
  setMassFromMass(b, 5);
  EXPECT_EQ(b.mass, 0);
  EXPECT_EQ(b.invMass, 0);
  EXPECT_EQ(b.inertia, Vec3::Zero());
  EXPECT_EQ(b.invInertia, Vec3::Zero());
}

TEST(Mass, RejectsShapesWithoutVolumeAndBadValues) {
  Body b;
  b.shape.type = ShapeType::Plane;
  EXPECT_THROW(setMassFromDensity(b, 1000), std::invalid_argument);
  b.shape.type = ShapeType::TriangleMesh;
  EXPECT_THROW(setMassFromMass(b, 1), std::invalid_argument);
  b.shape = sphere(1);
  EXPECT_THROW(setMassFromDensity(b, 0), std::invalid_argument);
  EXPECT_THROW(setMassFromMass(b, -1), std::invalid_argument);
}

#include "physics/mass.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace substep {

namespace {

constexpr double kPi = 3.14159265358979323846;

Mat3 diag(double x, double y, double z) { return Vec3(x, y, z).asDiagonal(); }

// Solids of revolution about local Y: only the axial and the transverse moments differ.
Mat3 axial(double transverse, double along) { return diag(transverse, along, transverse); }

}  // namespace

double meshVolume(const Mesh& mesh) { return meshMassProperties(mesh, 1.0).mass; }

MassProperties meshMassProperties(const Mesh& mesh, double density) {
  MassProperties mp;
  if (mesh.vertices.empty()) return mp;

  // Integrate over signed tetrahedra (o, a, b, c), one per triangle. Taking o at the vertex
  // mean instead of the file origin keeps the sums small for meshes far from their origin.
  Vec3 o = Vec3::Zero();
  for (const Vec3& v : mesh.vertices) o += v;
  o /= static_cast<double>(mesh.vertices.size());

  double vol = 0;
  Vec3 first = Vec3::Zero();   // ∫ x dV
  Mat3 second = Mat3::Zero();  // ∫ x xᵀ dV (covariance about o)
  for (const auto& t : mesh.triangles) {
    const Vec3 a = mesh.vertices[t[0]] - o;
    const Vec3 b = mesh.vertices[t[1]] - o;
    const Vec3 c = mesh.vertices[t[2]] - o;
    const double v = a.dot(b.cross(c)) / 6.0;
    const Vec3 s = a + b + c;
    vol += v;
    first += v * s / 4.0;
    // Tetrahedron with a vertex at the origin: ∫ x xᵀ = V/20 (Σ vᵢvᵢᵀ + s sᵀ) (Tonon 2004).
    second += (v / 20.0) * (a * a.transpose() + b * b.transpose() + c * c.transpose() + s * s.transpose());
  }

  mp.mass = density * vol;
  if (vol == 0) {
    mp.com = o;
    return mp;
  }
  const Vec3 r = first / vol;                        // centre of mass relative to o
  const Mat3 cov = density * (second - vol * r * r.transpose());  // about the centre of mass
  mp.com = o + r;
  mp.inertia = cov.trace() * Mat3::Identity() - cov;
  return mp;
}

MassProperties shapeMassProperties(const Shape& s, double density) {
  MassProperties mp;
  switch (s.type) {
    case ShapeType::Sphere: {
      const double r = s.radius;
      mp.mass = density * 4.0 / 3.0 * kPi * r * r * r;
      const double i = 0.4 * mp.mass * r * r;
      mp.inertia = diag(i, i, i);
      return mp;
    }
    case ShapeType::Box: {
      const Vec3 e = s.halfExtents;
      mp.mass = density * 8.0 * e.x() * e.y() * e.z();
      const Vec3 e2 = e.cwiseProduct(e);
      mp.inertia = diag(e2.y() + e2.z(), e2.x() + e2.z(), e2.x() + e2.y()) * (mp.mass / 3.0);
      return mp;
    }
    case ShapeType::Cylinder: {
      const double r = s.radius, h = s.halfHeight;
      mp.mass = density * kPi * r * r * 2.0 * h;
      mp.inertia = axial(mp.mass * (3.0 * r * r + 4.0 * h * h) / 12.0, 0.5 * mp.mass * r * r);
      return mp;
    }
    case ShapeType::Capsule: {
      const double r = s.radius, h = s.halfHeight;
      const double mc = density * kPi * r * r * 2.0 * h;          // the cylinder
      const double ms = density * 4.0 / 3.0 * kPi * r * r * r;    // both hemispheres together
      mp.mass = mc + ms;
      // Each hemisphere (mass ms/2) has its centre 3r/8 from its flat face, i.e. d = h + 3r/8 from
      // the capsule's centre. About that centre its transverse moment is (2/5 - 9/64) (ms/2) r²;
      // moving it by d adds (ms/2) d². Both together: ms (2r²/5 + h² + 3hr/4).
      const double cylT = mc * (3.0 * r * r + 4.0 * h * h) / 12.0;
      const double capT = ms * (0.4 * r * r + h * h + 0.75 * h * r);
      const double along = 0.5 * mc * r * r + 0.4 * ms * r * r;
      mp.inertia = axial(cylT + capT, along);
      return mp;
    }
    case ShapeType::ConvexMesh:
      if (!s.mesh) throw std::invalid_argument("convex shape without a mesh");
      return meshMassProperties(*s.mesh, density);
    case ShapeType::Plane:
    case ShapeType::TriangleMesh: break;
  }
  throw std::invalid_argument(std::string("a ") + shapeTypeName(s.type) + " has no volume; it can only be static");
}

Pose toPrincipalFrame(Mesh& mesh) {
  const MassProperties mp = meshMassProperties(mesh, 1.0);
  if (!(mp.mass > 0)) throw std::invalid_argument("mesh has no positive volume");

  const Mat3& I = mp.inertia;
  const double off = std::max({std::abs(I(0, 1)), std::abs(I(0, 2)), std::abs(I(1, 2))});
  Mat3 R = Mat3::Identity();
  // Already principal (a symmetric mesh authored along its axes): keep the author's axes rather
  // than let the solver reorder them by size.
  if (off > 1e-12 * I.trace()) {
    Eigen::SelfAdjointEigenSolver<Mat3> es(I);
    R = es.eigenvectors();
    if (R.determinant() < 0) R.col(2) = -R.col(2);  // a rotation, not a reflection
  }

  for (Vec3& v : mesh.vertices) v = R.transpose() * (v - mp.com);
  Pose pose;
  pose.p = mp.com;
  pose.q = Quat(R).normalized();
  return pose;
}

void setMassFromDensity(Body& b, double density) {
  if (b.isStatic) {
    b.mass = b.invMass = 0;
    b.inertia = b.invInertia = Vec3::Zero();
    return;
  }
  if (!(density > 0) || !std::isfinite(density))
    throw std::invalid_argument("density must be > 0, got " + std::to_string(density));
  const MassProperties mp = shapeMassProperties(b.shape, density);
  if (!(mp.mass > 0)) throw std::invalid_argument(std::string("the ") + shapeTypeName(b.shape.type) + " has no volume");

  // Bodies store principal moments only: the body origin must be the centre of mass and the
  // shape's axes principal (toPrincipalFrame does this for meshes).
  const double size = std::max(b.shape.boundingRadius(), 1e-12);
  const Mat3& I = mp.inertia;
  const double off = std::max({std::abs(I(0, 1)), std::abs(I(0, 2)), std::abs(I(1, 2))});
  if (mp.com.norm() > 1e-6 * size || off > 1e-6 * I.trace())
    throw std::invalid_argument("shape is not in its principal frame (centre of mass at the origin, principal axes)");

  b.mass = mp.mass;
  b.invMass = 1.0 / mp.mass;
  b.inertia = I.diagonal();
  b.invInertia = b.inertia.cwiseInverse();
}

void setMassFromMass(Body& b, double mass) {
  if (b.isStatic) {
    setMassFromDensity(b, 1.0);
    return;
  }
  if (!(mass > 0) || !std::isfinite(mass)) throw std::invalid_argument("mass must be > 0, got " + std::to_string(mass));
  const double volume = shapeMassProperties(b.shape, 1.0).mass;
  if (!(volume > 0)) throw std::invalid_argument(std::string("the ") + shapeTypeName(b.shape.type) + " has no volume");
  setMassFromDensity(b, mass / volume);
  b.mass = mass;  // exactly as given, not mass / volume * volume
  b.invMass = 1.0 / mass;
}

}  // namespace substep

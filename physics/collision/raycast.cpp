#include "physics/collision/raycast.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace substep {

namespace {

constexpr double kMiss = -1;

// Ray o + t d (|d| = 1) against a sphere of radius r at c: the smaller t >= 0.
double raySphere(const Vec3& o, const Vec3& d, const Vec3& c, double r) {
  const Vec3 m = o - c;
  const double b = m.dot(d), cc = m.squaredNorm() - r * r;
  if (cc <= 0) return 0;  // inside
  if (b > 0) return kMiss;
  const double disc = b * b - cc;
  return disc < 0 ? kMiss : -b - std::sqrt(disc);
}

// Slabs of a box of half extents h centred at the origin.
double rayBox(const Vec3& o, const Vec3& d, const Vec3& h, Vec3& n) {
  double t0 = 0, t1 = std::numeric_limits<double>::infinity();
  int axis = -1;
  double sign = 0;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d[i]) < 1e-300) {
      if (std::abs(o[i]) > h[i]) return kMiss;
      continue;
    }
    double a = (-h[i] - o[i]) / d[i], b = (h[i] - o[i]) / d[i];
    double s = -1;
    if (a > b) std::swap(a, b), s = 1;
    if (a > t0) t0 = a, axis = i, sign = s;
    t1 = std::min(t1, b);
    if (t0 > t1) return kMiss;
  }
  n = Vec3::Zero();
  if (axis >= 0) n[axis] = sign;
  else n = -d;  // inside
  return t0;
}

// A cylinder along Y (radius r, half height hh): the side, then both flat caps if `caps`
// (a capsule's ends are spheres instead).
double rayCylinder(const Vec3& o, const Vec3& d, double r, double hh, Vec3& n, bool caps = true) {
  double best = std::numeric_limits<double>::infinity();
  if (Vec3(o.x(), 0, o.z()).norm() <= r && std::abs(o.y()) <= hh) {
    n = -d;
    return 0;
  }
  const double a = d.x() * d.x() + d.z() * d.z();
  if (a > 1e-300) {
    const double b = o.x() * d.x() + o.z() * d.z(), c = o.x() * o.x() + o.z() * o.z() - r * r;
    const double disc = b * b - a * c;
    if (disc >= 0) {
      const double t = (-b - std::sqrt(disc)) / a;
      if (t >= 0 && std::abs(o.y() + t * d.y()) <= hh) best = t, n = Vec3(o.x() + t * d.x(), 0, o.z() + t * d.z()) / r;
    }
  }
  for (const double cap : {-hh, hh}) {
    if (!caps || std::abs(d.y()) < 1e-300) continue;
    const double t = (cap - o.y()) / d.y();
    const Vec3 p = o + t * d;
    if (t >= 0 && t < best && p.x() * p.x() + p.z() * p.z() <= r * r) best = t, n = Vec3(0, cap > 0 ? 1 : -1, 0);
  }
  return std::isinf(best) ? kMiss : best;
}

// Möller-Trumbore; both sides of the triangle.
double rayTriangle(const Vec3& o, const Vec3& d, const Vec3& a, const Vec3& b, const Vec3& c, Vec3& n) {
  const Vec3 e1 = b - a, e2 = c - a, p = d.cross(e2);
  const double det = e1.dot(p);
  if (std::abs(det) < 1e-300) return kMiss;
  const Vec3 s = o - a;
  const double u = s.dot(p) / det;
  if (u < 0 || u > 1) return kMiss;
  const Vec3 q = s.cross(e1);
  const double v = d.dot(q) / det, t = e2.dot(q) / det;
  if (v < 0 || u + v > 1 || t < 0) return kMiss;
  n = e1.cross(e2).normalized();
  if (n.dot(d) > 0) n = -n;
  return t;
}

}  // namespace

double rayShape(const Shape& s, const Vec3& o, const Vec3& d, Vec3& n) {
  switch (s.type) {
    case ShapeType::Sphere: {
      const double t = raySphere(o, d, Vec3::Zero(), s.radius);
      if (t >= 0) n = (o + t * d).normalized();
      return t;
    }
    case ShapeType::Box: return rayBox(o, d, s.halfExtents, n);
    case ShapeType::Cylinder: return rayCylinder(o, d, s.radius, s.halfHeight, n);
    case ShapeType::Capsule: {
      double best = rayCylinder(o, d, s.radius, s.halfHeight, n, false);
      for (const double end : {-s.halfHeight, s.halfHeight}) {
        const Vec3 c(0, end, 0);
        const double t = raySphere(o, d, c, s.radius);
        if (t >= 0 && (best < 0 || t < best)) best = t, n = (o + t * d - c).normalized();
      }
      return best;
    }
    case ShapeType::Plane: {
      const double side = s.normal.dot(o) - s.offset, along = s.normal.dot(d);
      n = s.normal;
      if (side <= 0) return 0;
      return along < 0 ? side / -along : kMiss;
    }
    case ShapeType::ConvexMesh:
    case ShapeType::TriangleMesh: {
      double best = kMiss;
      Vec3 tn;
      for (const auto& tri : s.mesh->triangles) {
        const double t = rayTriangle(o, d, s.mesh->vertices[static_cast<size_t>(tri[0])],
                                     s.mesh->vertices[static_cast<size_t>(tri[1])],
                                     s.mesh->vertices[static_cast<size_t>(tri[2])], tn);
        if (t >= 0 && (best < 0 || t < best)) best = t, n = tn;
      }
      return best;
    }
  }
  return kMiss;
}

RayHit raycast(const Model& model, const State& state, const Vec3& origin, const Vec3& direction, double maxDistance,
               bool dynamicOnly) {
  RayHit hit;
  const double len = direction.norm();
  if (!(len > 0) || !allFinite(origin) || !allFinite(direction)) return hit;
  const Vec3 d = direction / len;
  double best = maxDistance;
  for (size_t i = 0; i < model.bodies.size(); ++i) {
    const Body& b = model.bodies[i];
    if (dynamicOnly && b.isStatic) continue;
    const Pose pose = state.bodies[i].pose();
    // Cheap rejection by the bounding sphere (planes are unbounded).
    if (b.shape.type != ShapeType::Plane) {
      const double t = raySphere(origin, d, pose.p, b.shape.boundingRadius());
      if (t < 0 || t > best) continue;
    }
    Vec3 n;
    const double t = rayShape(b.shape, pose.unrotate(origin - pose.p), pose.unrotate(d), n);
    if (t < 0 || t > best) continue;
    best = t;
    hit.body = static_cast<int>(i);
    hit.distance = t;
    hit.point = origin + t * d;
    hit.normal = pose.rotate(n);
  }
  return hit;
}

}  // namespace substep

#include "physics/collision/shape_geometry.h"

#include "physics/collision/contact_margin.h"

#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/capsule.h>
#include <fcl/geometry/shape/convex.h>
#include <fcl/geometry/shape/cylinder.h>
#include <fcl/geometry/shape/halfspace.h>
#include <fcl/geometry/shape/sphere.h>
#include <fcl/math/bv/OBBRSS.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace substep {

CollisionShape makeCollisionShape(const Shape& s) {
  CollisionShape c;
  switch (s.type) {
    case ShapeType::Sphere: c.geometry = std::make_shared<fcl::Sphered>(s.radius); break;
    case ShapeType::Box: c.geometry = std::make_shared<fcl::Boxd>(2.0 * s.halfExtents); break;
    case ShapeType::Capsule:
    case ShapeType::Cylinder:
      if (s.type == ShapeType::Capsule)
        c.geometry = std::make_shared<fcl::Capsuled>(s.radius, 2.0 * s.halfHeight);
      else
        c.geometry = std::make_shared<fcl::Cylinderd>(s.radius, 2.0 * s.halfHeight);
      // FCL's axis is Z; ours is Y. Rx(-90°) maps Z to Y.
      c.offset.q = Quat(Eigen::AngleAxisd(-M_PI / 2, Vec3::UnitX()));
      break;
    case ShapeType::ConvexMesh: {
      auto verts = std::make_shared<std::vector<Vec3>>(s.mesh->vertices);
      auto faces = std::make_shared<std::vector<int>>();
      for (const auto& t : s.mesh->triangles) {
        faces->push_back(3);
        faces->insert(faces->end(), t.begin(), t.end());
      }
      // Checked closed when loaded (closedSurfaceProblem): FCL need not check again, and its own
      // message runs to a line per edge.
      c.geometry = std::make_shared<fcl::Convexd>(verts, static_cast<int>(s.mesh->triangles.size()), faces, false);
      break;
    }
    case ShapeType::Plane: c.geometry = std::make_shared<fcl::Halfspaced>(s.normal, s.offset); break;
    case ShapeType::TriangleMesh: {
      auto m = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
      std::vector<fcl::Triangle> tris;
      tris.reserve(s.mesh->triangles.size());
      for (const auto& t : s.mesh->triangles) tris.emplace_back(t[0], t[1], t[2]);
      m->beginModel();
      m->addSubModel(s.mesh->vertices, tris);
      m->endModel();
      c.geometry = m;
      break;
    }
  }
  c.geometry->computeLocalAABB();
  return c;
}

namespace {

// Writes the convex hull of points lying near a plane with normal d into f, counter-clockwise
// about d (monotone chain), so a face comes out as a polygon the clipper can use. At most
// kMaxFeaturePoints are kept, spread evenly around the hull.
void hullInto(const Vec3* pts, int n, const Vec3& d, Feature& f) {
  f.count = 0;
  if (n < 3) {
    for (int i = 0; i < n; ++i) f.p[f.count++] = pts[i];
    return;
  }
  Vec3 t1, t2;
  tangentBasis(d, t1, t2);
  struct P2 {
    double x, y;
    int i;
  };
  P2 sorted[64];
  n = std::min(n, 64);
  for (int i = 0; i < n; ++i) sorted[i] = {pts[i].dot(t1), pts[i].dot(t2), i};
  std::sort(sorted, sorted + n, [](const P2& a, const P2& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
  auto cross = [](const P2& o, const P2& a, const P2& b) { return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x); };
  P2 hull[130];
  int k = 0;
  for (int i = 0; i < n; ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], sorted[i]) <= 0) --k;
    hull[k++] = sorted[i];
  }
  for (int i = n - 2, t = k + 1; i >= 0; --i) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], sorted[i]) <= 0) --k;
    hull[k++] = sorted[i];
  }
  const int h = k > 1 ? k - 1 : k;
  const int m = std::min(h, kMaxFeaturePoints);
  for (int i = 0; i < m; ++i) f.p[f.count++] = pts[hull[i * h / m].i];
}

}  // namespace

Feature supportingFeature(const Shape& s, const Pose& pose, const Vec3& dWorld) {
  Feature f;
  const Vec3 d = pose.unrotate(dWorld);  // body frame
  // A face (or a capsule's side line) supports as a whole while it is within kFeatureAngle of
  // facing d: a loaded box tilts by fractions of a degree and must keep its four corners, not
  // rock on an edge. Corners lifted beyond the contact margin are dropped by the clipping.
  const double across = std::sin(kFeatureAngle);
  auto out = [&](const Vec3& local) { f.p[f.count++] = pose.apply(local); };
  switch (s.type) {
    case ShapeType::Sphere: out(s.radius * d); break;
    case ShapeType::Box: {
      const Vec3& h = s.halfExtents;
      Vec3 corner;
      bool free[3];
      for (int i = 0; i < 3; ++i) {
        corner[i] = d[i] >= 0 ? h[i] : -h[i];
        free[i] = std::abs(d[i]) <= across;
      }
      // Enumerate the corners reachable by flipping the free axes (1, 2 or 4 of them).
      int axes[3], na = 0;
      for (int i = 0; i < 3; ++i)
        if (free[i]) axes[na++] = i;
      if (na == 3) na = 2;  // d ~ 0: cannot happen for a unit direction; keep a face
      if (na == 0) {
        out(corner);
      } else if (na == 1) {
        Vec3 c2 = corner;
        c2[axes[0]] = -c2[axes[0]];
        out(corner);
        out(c2);
      } else {
        // Face: walk the four corners in order.
        const int i = axes[0], j = axes[1];
        Vec3 c = corner;
        out(c);
        c[i] = -c[i];
        out(c);
        c[j] = -c[j];
        out(c);
        c[i] = -c[i];
        out(c);
      }
      break;
    }
    case ShapeType::Capsule:
    case ShapeType::Cylinder: {
      const double ay = d.y();
      Vec3 radial(d.x(), 0, d.z());
      const double rn = radial.norm();
      const bool capsule = s.type == ShapeType::Capsule;
      if (capsule) {
        if (std::abs(ay) <= across) {  // lying across d: its side line
          out(Vec3(0, s.halfHeight, 0) + s.radius * d);
          out(Vec3(0, -s.halfHeight, 0) + s.radius * d);
        } else {
          out(Vec3(0, ay > 0 ? s.halfHeight : -s.halfHeight, 0) + s.radius * d);
        }
        break;
      }
      const double y = ay >= 0 ? s.halfHeight : -s.halfHeight;
      if (rn <= across) {  // cap facing d: the rim as an octagon
        for (int k = 0; k < 8; ++k) {
          const double a = k * M_PI / 4;
          out(Vec3(s.radius * std::cos(a), y, s.radius * std::sin(a)));
        }
      } else {
        const Vec3 r = radial / rn * s.radius;
        if (std::abs(ay) <= across) {  // side line
          out(Vec3(r.x(), s.halfHeight, r.z()));
          out(Vec3(r.x(), -s.halfHeight, r.z()));
        } else {
          out(Vec3(r.x(), y, r.z()));
        }
      }
      break;
    }
    case ShapeType::ConvexMesh: {
      double best = -1e300;
      for (const Vec3& v : s.mesh->vertices) best = std::max(best, v.dot(d));
      // A mesh has no face list here: vertices within a small angle of the support plane, over
      // the mesh's size, make the face (kFeatureAngle would merge neighbouring faces).
      const double tol = std::max(kContactMargin, 2.0 * s.boundingRadius() * std::sin(kMeshFeatureAngle));
      Vec3 near[64];
      int n = 0;
      for (const Vec3& v : s.mesh->vertices)
        if (v.dot(d) >= best - tol && n < 64) near[n++] = pose.apply(v);
      hullInto(near, n, dWorld, f);
      break;
    }
    case ShapeType::Plane:
    case ShapeType::TriangleMesh:
      throw std::logic_error("supportingFeature: planes and triangle meshes are not convex solids");
  }
  return f;
}

}  // namespace substep

#include "render/meshes.h"

#include <cmath>
#include <stdexcept>

namespace substep::render {

namespace {

constexpr float kPi = 3.14159265358979f;

void addVertex(MeshData& m, const Vec3f& p, const Vec3f& n, float cap = 0) {
  m.vertices.push_back({{p.x(), p.y(), p.z()}, {n.x(), n.y(), n.z()}, cap});
}

void addQuad(MeshData& m, uint32_t a, uint32_t b, uint32_t c, uint32_t d) {
  m.indices.insert(m.indices.end(), {a, b, c, a, c, d});
}

// Rings of a unit sphere from latitude lat0 to lat1 (radians, -π/2 .. π/2), `rings` bands.
void addSphereBand(MeshData& m, int slices, int rings, float lat0, float lat1, float cap) {
  const uint32_t base = static_cast<uint32_t>(m.vertices.size());
  for (int r = 0; r <= rings; ++r) {
    const float lat = lat0 + (lat1 - lat0) * r / rings;
    for (int s = 0; s <= slices; ++s) {
      const float lon = 2 * kPi * s / slices;
      const Vec3f d(std::cos(lat) * std::sin(lon), std::sin(lat), std::cos(lat) * std::cos(lon));
      addVertex(m, d, d, cap);
    }
  }
  const uint32_t row = static_cast<uint32_t>(slices + 1);
  for (int r = 0; r < rings; ++r)
    for (int s = 0; s < slices; ++s) {
      const uint32_t a = base + r * row + s;
      // Counter-clockwise from outside: latitude grows upwards, longitude eastwards.
      addQuad(m, a, a + 1, a + row + 1, a + row);
    }
}

}  // namespace

MeshData boxMesh() {
  MeshData m;
  for (int axis = 0; axis < 3; ++axis)
    for (int sign = -1; sign <= 1; sign += 2) {
      Vec3f n = Vec3f::Zero();
      n[axis] = static_cast<float>(sign);
      // Two tangents with u × v = n, so the corners run counter-clockwise seen from outside.
      Vec3f u = Vec3f::Zero();
      u[(axis + 1) % 3] = 1;
      const Vec3f v = n.cross(u);
      const uint32_t base = static_cast<uint32_t>(m.vertices.size());
      addVertex(m, n - u - v, n);
      addVertex(m, n + u - v, n);
      addVertex(m, n + u + v, n);
      addVertex(m, n - u + v, n);
      addQuad(m, base, base + 1, base + 2, base + 3);
    }
  return m;
}

MeshData sphereMesh(int slices, int stacks) {
  MeshData m;
  addSphereBand(m, slices, stacks, -kPi / 2, kPi / 2, 0);
  return m;
}

MeshData capsuleMesh(int slices, int ringsPerCap) {
  MeshData m;
  addSphereBand(m, slices, ringsPerCap, -kPi / 2, 0, -1);  // lower hemisphere, moved down by the stretch
  addSphereBand(m, slices, ringsPerCap, 0, kPi / 2, +1);   // upper, moved up
  // The side: the lower cap's equator to the upper cap's (same unit positions, opposite cap signs).
  const uint32_t row = static_cast<uint32_t>(slices + 1);
  const uint32_t lowerEquator = ringsPerCap * row;                     // last ring of the lower band
  const uint32_t upperEquator = (ringsPerCap + 1) * row;               // first ring of the upper band
  for (int s = 0; s < slices; ++s)
    addQuad(m, lowerEquator + s, lowerEquator + s + 1, upperEquator + s + 1, upperEquator + s);
  return m;
}

MeshData cylinderMesh(int slices) {
  MeshData m;
  const uint32_t side = 0;
  for (int s = 0; s <= slices; ++s) {
    const float lon = 2 * kPi * s / slices;
    const Vec3f n(std::sin(lon), 0, std::cos(lon));
    addVertex(m, n - Vec3f::UnitY(), n);
    addVertex(m, n + Vec3f::UnitY(), n);
  }
  for (int s = 0; s < slices; ++s) {
    const uint32_t a = side + 2 * s;
    addQuad(m, a, a + 2, a + 3, a + 1);
  }
  for (int sign = -1; sign <= 1; sign += 2) {
    const Vec3f n(0, static_cast<float>(sign), 0);
    const uint32_t centre = static_cast<uint32_t>(m.vertices.size());
    addVertex(m, n, n);
    for (int s = 0; s <= slices; ++s) {
      const float lon = 2 * kPi * s / slices;
      addVertex(m, Vec3f(std::sin(lon), static_cast<float>(sign), std::cos(lon)), n);
    }
    for (int s = 0; s < slices; ++s) {
      const uint32_t a = centre + 1 + s;
      if (sign > 0)
        m.indices.insert(m.indices.end(), {centre, a, a + 1});
      else
        m.indices.insert(m.indices.end(), {centre, a + 1, a});
    }
  }
  return m;
}

MeshData quadMesh() {
  MeshData m;
  const Vec3f n = Vec3f::UnitY();
  addVertex(m, Vec3f(-1, 0, -1), n);
  addVertex(m, Vec3f(-1, 0, 1), n);
  addVertex(m, Vec3f(1, 0, 1), n);
  addVertex(m, Vec3f(1, 0, -1), n);
  addQuad(m, 0, 1, 2, 3);
  return m;
}

MeshData coneMesh(int slices) {
  MeshData m;
  // The side's normal leans up by the slope: the surface rises 2 while it narrows by 1. Each
  // slice has its own apex vertex, with the normal of the slice's middle.
  const float ny = 1 / std::sqrt(5.0f), nr = 2 / std::sqrt(5.0f);
  for (int s = 0; s < slices; ++s) {
    const float lon0 = 2 * kPi * s / slices, lon1 = 2 * kPi * (s + 1) / slices, mid = 0.5f * (lon0 + lon1);
    const uint32_t a = static_cast<uint32_t>(m.vertices.size());
    addVertex(m, Vec3f(std::sin(lon0), -1, std::cos(lon0)), Vec3f(nr * std::sin(lon0), ny, nr * std::cos(lon0)));
    addVertex(m, Vec3f(std::sin(lon1), -1, std::cos(lon1)), Vec3f(nr * std::sin(lon1), ny, nr * std::cos(lon1)));
    addVertex(m, Vec3f(0, 1, 0), Vec3f(nr * std::sin(mid), ny, nr * std::cos(mid)));
    m.indices.insert(m.indices.end(), {a, a + 1, a + 2});
  }
  const Vec3f down = -Vec3f::UnitY();
  const uint32_t centre = static_cast<uint32_t>(m.vertices.size());
  addVertex(m, down, down);
  for (int s = 0; s <= slices; ++s) {
    const float lon = 2 * kPi * s / slices;
    addVertex(m, Vec3f(std::sin(lon), -1, std::cos(lon)), down);
  }
  for (int s = 0; s < slices; ++s) {
    const uint32_t a = centre + 1 + s;
    m.indices.insert(m.indices.end(), {centre, a + 1, a});
  }
  return m;
}

bool isRound(int meshId) {
  return meshId == kSphereMesh || meshId == kCapsuleMesh || meshId == kCylinderMesh || meshId == kConeMesh;
}

int roundLevel(float radiusPixels, float maxError) {
  for (int level = 0; level < kFinestLevel; ++level)
    if (radiusPixels * (1 - std::cos(kPi / static_cast<float>(kRoundSlices[level]))) <= maxError) return level;
  return kFinestLevel;
}

MeshData primitiveMesh(int id, int level) {
  if (level < 0 || level >= kRoundLevels) throw std::invalid_argument("primitiveMesh: no level " + std::to_string(level));
  const int n = kRoundSlices[level];
  switch (id) {
    case kBoxMesh: return boxMesh();
    case kSphereMesh: return sphereMesh(n, n / 2);
    case kCapsuleMesh: return capsuleMesh(n, n / 4);
    case kCylinderMesh: return cylinderMesh(n);
    case kQuadMesh: return quadMesh();
    case kConeMesh: return coneMesh(n);
    default: throw std::invalid_argument("primitiveMesh: no primitive with id " + std::to_string(id));
  }
}

MeshData modelMesh(const Mesh& mesh, double creaseDegrees) {
  const size_t nt = mesh.triangles.size();
  std::vector<Vec3f> faceN(nt);       // area-weighted (unnormalised) face normals
  std::vector<std::vector<int>> facesOf(mesh.vertices.size());
  for (size_t t = 0; t < nt; ++t) {
    const auto& tri = mesh.triangles[t];
    const Vec3f a = mesh.vertices[tri[0]].cast<float>(), b = mesh.vertices[tri[1]].cast<float>(),
                c = mesh.vertices[tri[2]].cast<float>();
    faceN[t] = (b - a).cross(c - a);
    for (int k = 0; k < 3; ++k) facesOf[tri[k]].push_back(static_cast<int>(t));
  }
  const float cosCrease = static_cast<float>(std::cos(creaseDegrees * kPi / 180.0));
  MeshData m;
  m.vertices.reserve(3 * nt);
  for (size_t t = 0; t < nt; ++t) {
    const Vec3f own = faceN[t].normalized();
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles[t][k];
      // Smooth over the neighbours that meet this face at less than the crease angle.
      Vec3f n = Vec3f::Zero();
      for (int f : facesOf[v])
        if (faceN[f].normalized().dot(own) >= cosCrease) n += faceN[f];
      n = n.norm() > 0 ? n.normalized() : own;
      addVertex(m, mesh.vertices[v].cast<float>(), n);
      m.indices.push_back(static_cast<uint32_t>(m.vertices.size() - 1));
    }
  }
  return m;
}

}  // namespace substep::render

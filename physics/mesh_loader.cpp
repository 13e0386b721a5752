#include "physics/mesh_loader.h"

#include "physics/limits.h"
#include "physics/scene_file.h"

#include <assimp/Importer.hpp>
#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>

namespace substep {

namespace {

void addNode(const aiScene& scene, const aiNode& node, const aiMatrix4x4& parent, Mesh& out, double scale) {
  const aiMatrix4x4 m = parent * node.mTransformation;
  for (unsigned i = 0; i < node.mNumMeshes; ++i) {
    const aiMesh& mesh = *scene.mMeshes[node.mMeshes[i]];
    const int base = static_cast<int>(out.vertices.size());
    for (unsigned k = 0; k < mesh.mNumVertices; ++k) {
      const aiVector3D v = m * mesh.mVertices[k];
      out.vertices.emplace_back(scale * v.x, scale * v.y, scale * v.z);
    }
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      const aiFace& face = mesh.mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines have no surface
      out.triangles.push_back({base + static_cast<int>(face.mIndices[0]), base + static_cast<int>(face.mIndices[1]),
                               base + static_cast<int>(face.mIndices[2])});
    }
  }
  for (unsigned c = 0; c < node.mNumChildren; ++c) addNode(scene, *node.mChildren[c], m, out, scale);
}

}  // namespace

Mesh loadMesh(const std::string& path, double scale) {
  if (!(scale > 0) || !std::isfinite(scale)) throw SceneError(path, "", "scale must be > 0, got " + std::to_string(scale));

  // Check readability ourselves: assimp's message for a missing file does not give the reason,
  // and it would block on a FIFO and read /dev/zero until memory runs out.
  if (const std::string why = checkInputFile(path, limits::kMaxMeshBytes); !why.empty()) throw SceneError(path, "", why);

  Assimp::Importer importer;
  // Drop normals, UVs and colours so JoinIdenticalVertices welds by position alone: a convex hull
  // and the mass integrals want one vertex per corner, not one per face.
  importer.SetPropertyInteger(AI_CONFIG_PP_RVC_FLAGS, aiComponent_NORMALS | aiComponent_TANGENTS_AND_BITANGENTS |
                                                          aiComponent_COLORS | aiComponent_TEXCOORDS);
  const aiScene* scene =
      importer.ReadFile(path, aiProcess_RemoveComponent | aiProcess_Triangulate | aiProcess_JoinIdenticalVertices);
  if (!scene || !scene->mRootNode) {
    std::string why = importer.GetErrorString();
    if (why.empty()) why = "unknown error";
    throw SceneError(path, "", "cannot read mesh: " + why);
  }

  Mesh mesh;
  mesh.file = path;
  addNode(*scene, *scene->mRootNode, aiMatrix4x4(), mesh, scale);
  if (mesh.triangles.empty()) throw SceneError(path, "", "the file holds no triangles");
  if (mesh.triangles.size() > limits::kMaxMeshTriangles)
    throw SceneError(path, "", "the file holds " + std::to_string(mesh.triangles.size()) + " triangles; expected at most " +
                                   std::to_string(limits::kMaxMeshTriangles));
  for (const Vec3& v : mesh.vertices)
    if (!allFinite(v)) throw SceneError(path, "", "the file has a vertex with a non-finite coordinate");
  // Vertices no triangle uses (a point cloud's leftovers) would be supporting points of nothing.
  std::vector<int> used(mesh.vertices.size(), -1);
  std::vector<Vec3> kept;
  for (auto& t : mesh.triangles)
    for (int& i : t) {
      if (used[static_cast<size_t>(i)] < 0) {
        used[static_cast<size_t>(i)] = static_cast<int>(kept.size());
        kept.push_back(mesh.vertices[static_cast<size_t>(i)]);
      }
      i = used[static_cast<size_t>(i)];
    }
  mesh.vertices.swap(kept);
  return mesh;
}

std::string closedSurfaceProblem(const Mesh& m) {
  // Every edge of a closed surface borders exactly two triangles.
  std::map<std::pair<int, int>, int> edges;
  for (const auto& t : m.triangles)
    for (int k = 0; k < 3; ++k) {
      int a = t[static_cast<size_t>(k)], b = t[static_cast<size_t>((k + 1) % 3)];
      if (a == b) return "it has a degenerate triangle (two corners at one vertex)";
      if (a > b) std::swap(a, b);
      ++edges[{a, b}];
    }
  long long open = 0, crowded = 0;
  std::pair<int, int> first{-1, -1};
  for (const auto& [e, count] : edges) {
    if (count == 2) continue;
    (count < 2 ? open : crowded) += 1;
    if (first.first < 0) first = e;
  }
  if (open + crowded == 0) return "";
  std::string why = "it is not a closed surface: ";
  if (open) why += std::to_string(open) + " edges border one triangle only";
  if (open && crowded) why += " and ";
  if (crowded) why += std::to_string(crowded) + " edges border three or more";
  auto at = [&](int i) {
    const Vec3& v = m.vertices[static_cast<size_t>(i)];
    return "(" + numberText(v.x()) + ", " + numberText(v.y()) + ", " + numberText(v.z()) + ")";
  };
  return why + " (the first from " + at(first.first) + " to " + at(first.second) +
         "); a convex shape needs a closed hull, e.g. from your modeller's convex-hull tool";
}

}  // namespace substep

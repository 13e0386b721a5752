#include "physics/mesh_loader.h"

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

  // Check readability ourselves: assimp's message for a missing file does not give the reason.
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw SceneError(path, "", std::string("cannot open: ") + std::strerror(EISDIR));
  if (FILE* f = std::fopen(path.c_str(), "rb")) {
    std::fclose(f);
  } else {
    throw SceneError(path, "", std::string("cannot open: ") + std::strerror(errno));
  }

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
  for (const Vec3& v : mesh.vertices)
    if (!allFinite(v)) throw SceneError(path, "", "the file has a vertex with a non-finite coordinate");
  return mesh;
}

}  // namespace substep

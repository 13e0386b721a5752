// Triangle meshes from asset files (OBJ, STL, PLY, ... whatever assimp reads).
#pragma once

#include "physics/model.h"

#include <string>

namespace substep {

// Loads every triangle of the file (all meshes, node transforms applied), welds vertices at the
// same position and multiplies the coordinates by `scale` (> 0). Mesh::file is set to `path`.
// Throws SceneError(path, "", message) when the file cannot be read or holds no triangles;
// scene parsing re-throws it with the scene file and JSON path.
// Vertices no triangle uses are dropped. The file must be a regular file (scene_file.h,
// checkInputFile) of at most limits::kMaxMeshBytes, with at most limits::kMaxMeshTriangles.
Mesh loadMesh(const std::string& path, double scale = 1.0);

// Why the mesh is not a closed surface (every edge shared by exactly two triangles), in one
// line, or "" if it is. Convex shapes must be closed: FCL's convex support walks the edges.
std::string closedSurfaceProblem(const Mesh& m);

}  // namespace substep

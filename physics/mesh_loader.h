// Triangle meshes from asset files (OBJ, STL, PLY, ... whatever assimp reads).
#pragma once

#include "physics/model.h"

#include <string>

namespace substep {

// Loads every triangle of the file (all meshes, node transforms applied), welds vertices at the
// same position and multiplies the coordinates by `scale` (> 0). Mesh::file is set to `path`.
// Throws SceneError(path, "", message) when the file cannot be read or holds no triangles;
// scene parsing re-throws it with the scene file and JSON path.
Mesh loadMesh(const std::string& path, double scale = 1.0);

}  // namespace substep

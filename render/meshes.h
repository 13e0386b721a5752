// Triangle meshes for the GPU, built on the CPU: the unit primitives (generated once per
// renderer) and the model's convex and triangle meshes.
#pragma once

#include "physics/model.h"
#include "render/draw_list.h"

#include <cstdint>
#include <vector>

namespace substep::render {

struct MeshVertex {
  float position[3];
  float normal[3];
  float capSign;  // capsule: +1 upper hemisphere, -1 lower, 0 elsewhere (see Instance)
};

struct MeshData {
  std::vector<MeshVertex> vertices;
  std::vector<uint32_t> indices;  // triangles, counter-clockwise seen from outside
};

// Unit primitives, as Instance scales them:
//   box: half extents 1;  sphere: radius 1;  capsule: radius 1, hemispheres split at y = 0;
//   cylinder: radius 1, half height 1 (axis Y);  quad: the square [-1,1]² in the XZ plane, normal +Y.
MeshData boxMesh();
MeshData sphereMesh(int slices = 32, int stacks = 16);
MeshData capsuleMesh(int slices = 32, int ringsPerCap = 8);
MeshData cylinderMesh(int slices = 32);
MeshData quadMesh();
MeshData primitiveMesh(int id);

// A model mesh with normals smoothed across edges sharper than `creaseDegrees` kept sharp, so a
// gem stays faceted and a bowl looks round.
MeshData modelMesh(const Mesh& mesh, double creaseDegrees = 35);

}  // namespace substep::render

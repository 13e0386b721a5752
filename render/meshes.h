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
//   cylinder: radius 1, half height 1 (axis Y);  quad: the square [-1,1]² in the XZ plane, normal +Y;
//   cone: base of radius 1 at y = -1, apex at y = +1 (arrow heads).
MeshData boxMesh();
MeshData sphereMesh(int slices = 32, int stacks = 16);
MeshData capsuleMesh(int slices = 32, int ringsPerCap = 8);
MeshData cylinderMesh(int slices = 32);
MeshData quadMesh();
MeshData coneMesh(int slices = 32);

// Levels of detail of the round primitives (sphere, capsule, cylinder): slices around the axis,
// the finest (32, with 16 stacks, 8 rings per capsule cap) the one used for everything before.
// A circle of radius r drawn with n slices misses it by at most r (1 - cos(π/n)) at an edge's
// middle; on screen that is what a coarser level costs.
inline constexpr int kRoundSlices[] = {8, 12, 16, 20, 24, 32};
inline constexpr int kRoundLevels = 6;
inline constexpr int kFinestLevel = kRoundLevels - 1;
// Largest silhouette error a level may make: half a pixel on screen, half a texel in the shadow
// map (its lookup blends 2x2 texels): at 4x zoom the frames look the same as with 32 slices
// everywhere; what changes is which side of a silhouette some edge pixels fall on. What the
// levels save is measured in docs/rendering.md.
inline constexpr float kMaxSilhouetteError = 0.5f;
inline constexpr float kMaxShadowSilhouetteError = 0.5f;
bool isRound(int meshId);  // sphere, capsule, cylinder, cone
// The coarsest level whose silhouette of a circle `radiusPixels` across stays within `maxError`.
int roundLevel(float radiusPixels, float maxError = kMaxSilhouetteError);
// A primitive at a level of detail (boxes and quads have one).
MeshData primitiveMesh(int id, int level = kFinestLevel);

// A model mesh with normals smoothed across edges sharper than `creaseDegrees` kept sharp, so a
// gem stays faceted and a bowl looks round.
MeshData modelMesh(const Mesh& mesh, double creaseDegrees = 35);

}  // namespace substep::render

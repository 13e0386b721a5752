// The abstract draw list: what a frame shows, with no GL in it. The scene builder (scene_builder.h)
// fills it from a physics state; the GL backend (gl_renderer.h) draws it. The split is MuJoCo's
// (mjvScene / mjrContext): tests can check what would be drawn without a context, and one list
// can be drawn into any viewport of a frame (comparison grids).
#pragma once

#include "physics/model.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace substep::render {

using Vec3f = Eigen::Vector3f;
using Vec4f = Eigen::Vector4f;
using Quatf = Eigen::Quaternionf;
using Mat4f = Eigen::Matrix4f;

// Meshes the backend generates once (render/meshes.h); ids from kFirstCustomMesh on index
// DrawList::meshes (convex and triangle meshes of the model, in body coordinates).
enum MeshId : int { kBoxMesh = 0, kSphereMesh, kCapsuleMesh, kCylinderMesh, kQuadMesh, kConeMesh, kFirstCustomMesh };

enum InstanceFlags : uint32_t {
  kGrid = 1u,        // draw a 1 m / 5 m grid on its upward faces (grounds)
  kNoShadow = 2u,    // casts no shadow (overlays, huge planes)
};

// One instance of a mesh. A vertex v of the mesh lands at
//   position + rotation * (scale ∘ v + stretch * capSign(v) * ŷ)
// where capSign is +1/-1 on a capsule's upper/lower hemisphere and 0 elsewhere, so one unit
// capsule mesh serves every radius (scale) and half-height (stretch).
struct Instance {
  int mesh = kBoxMesh;
  Vec3f position = Vec3f::Zero();
  Quatf rotation = Quatf::Identity();
  Vec3f scale = Vec3f::Ones();
  float stretch = 0;
  Vec4f colour = Vec4f(0.7f, 0.7f, 0.7f, 1.0f);  // linear-ish RGB in [0,1], alpha
  float highlight = 0;                            // 0..1: glow mixed in (picked bodies)
  uint32_t flags = 0;
  int body = -1;                                  // the model's body, -1 for overlays
};

struct Camera {
  Vec3f eye = Vec3f(0, 2, 10);
  Vec3f target = Vec3f::Zero();
  Vec3f up = Vec3f::UnitY();
  float fovY = 45;             // degrees, for viewports at least `fitAspect` wide
  float fitAspect = 16.0f / 9;  // narrower viewports (grid panels) widen fovY to keep the width in view
  float zNear = 0.05f, zFar = 500;

  Mat4f view() const;
  Mat4f projection(float aspect) const;
};

struct TextLine {
  std::string text;            // UTF-8
  Vec4f colour = Vec4f(1, 1, 1, 1);
};

struct DrawList {
  std::vector<std::shared_ptr<const Mesh>> meshes;  // mesh id kFirstCustomMesh + i
  std::vector<Instance> solids;                     // lit, shadowed, depth tested
  std::vector<Instance> overlays;                   // contacts, joints, forces: flat colour, drawn over the solids
  Camera camera;
  Vec3f lightDirection = Vec3f(0.5f, -1.0f, -0.45f).normalized();  // direction the light travels: from the upper left, in front
  Vec3f boundsCentre = Vec3f::Zero();  // what the shadow map must cover
  float boundsRadius = 10;
  std::string label;                   // large, top centre: the setting of a comparison panel
  Vec4f labelColour = Vec4f(1, 1, 1, 1);
  std::vector<TextLine> hud;           // top left
  std::vector<TextLine> footer;        // bottom left: legend
};

}  // namespace substep::render

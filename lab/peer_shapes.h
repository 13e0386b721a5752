// What every peer maps of a scene's bodies: spheres, boxes, capsules, cylinders and static planes.
// The peers' own checks (lab/*_peer.cpp) start with this one.
#pragma once

#include "physics/model.h"

#include <string>

namespace substep::lab {

// Why a body is no shape the peer `engine` ("Bullet", "ODE", "MuJoCo") maps, or "" when all are.
inline std::string unmappedBody(const Model& model, const std::string& engine) {
  for (const Body& b : model.bodies) {
    const ShapeType t = b.shape.type;
    if (t == ShapeType::ConvexMesh || t == ShapeType::TriangleMesh)
      return "body \"" + b.name + "\" is a " + shapeTypeName(t) + " (the " + engine +
             " peer maps spheres, boxes, capsules, cylinders and static planes)";
    if (t == ShapeType::Plane && !b.isStatic) return "body \"" + b.name + "\" is a dynamic plane";
  }
  return {};
}

}  // namespace substep::lab

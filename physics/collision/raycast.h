// A ray against the bodies of a state: which body a viewer points at (the server's picking), in
// closed form for every shape (meshes triangle by triangle). Not part of a step.
#pragma once

#include "physics/model.h"
#include "physics/state.h"

namespace substep {

struct RayHit {
  int body = -1;             // -1: nothing within maxDistance
  double distance = 0;       // along the (unit) direction [m]
  Vec3 point = Vec3::Zero(); // world [m]
  Vec3 normal = Vec3::UnitY();
};

// The nearest surface a ray from `origin` along `direction` (any length, not zero) meets within
// maxDistance. Rays starting inside a body hit it at distance 0. `dynamicOnly` skips static bodies.
RayHit raycast(const Model& model, const State& state, const Vec3& origin, const Vec3& direction, double maxDistance,
               bool dynamicOnly = false);

// The distance along a unit ray (body frame) to a shape's surface, or a negative number.
double rayShape(const Shape& shape, const Vec3& origin, const Vec3& direction, Vec3& normal);

}  // namespace substep

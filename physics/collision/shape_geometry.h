// What collision needs of a shape: its FCL geometry and its supporting feature in a direction.
#pragma once

#include "physics/math.h"
#include "physics/model.h"

#include <fcl/geometry/collision_geometry.h>

#include <memory>
#include <vector>

namespace substep {

// FCL geometry of a shape, plus the fixed transform from the body frame to FCL's shape frame
// (FCL's capsules and cylinders lie along Z, ours along Y).
struct CollisionShape {
  std::shared_ptr<fcl::CollisionGeometryd> geometry;
  Pose offset;  // FCL shape frame expressed in the body frame
};
CollisionShape makeCollisionShape(const Shape& shape);

// The supporting feature of a convex shape in world direction d: the points of its surface that
// are furthest along d, within an angular tolerance (a face gives its polygon in order, an edge
// two points, a vertex or a round surface one). World coordinates.
// Maximum polygon size is kMaxFeaturePoints.
constexpr int kMaxFeaturePoints = 8;
struct Feature {
  Vec3 p[kMaxFeaturePoints];
  int count = 0;
};
Feature supportingFeature(const Shape& shape, const Pose& pose, const Vec3& d);

}  // namespace substep

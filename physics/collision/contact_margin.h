#pragma once

#include <cmath>

namespace substep {

// Contact points within this distance of touching are kept in a manifold as speculative points
// (their bias lets the bodies close the gap in one step and no further) [m]. Bodies that move
// add the distance they can cover in a step (world.cpp); this is the part for resting ones, and
// the tolerance within which points belong to a supporting face.
constexpr double kContactMargin = 0.005;

// A face supports as a whole while it is within this angle of facing the contact normal [rad]
// (shape_geometry.cpp); for convex meshes, whose faces are not known as such, a smaller one.
constexpr double kFeatureAngle = 10.0 * M_PI / 180.0;
constexpr double kMeshFeatureAngle = 2.0 * M_PI / 180.0;

}  // namespace substep

#pragma once

namespace substep {

// Contact points within this distance of touching are kept in a manifold as speculative points
// (their bias lets the bodies close the gap in one step and no further) [m]. Bodies that move
// add the distance they can cover in a step (world.cpp); this is the part for resting ones, and
// the tolerance within which points belong to a supporting face.
constexpr double kContactMargin = 0.005;

}  // namespace substep

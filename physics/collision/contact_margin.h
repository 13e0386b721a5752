#pragma once

namespace substep {

// Contact points separated by less than this are kept in a manifold as speculative points
// (their bias lets the bodies approach by the gap in one step, no more) [m].
constexpr double kContactMargin = 0.02;

}  // namespace substep

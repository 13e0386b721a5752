// Ball-and-socket joint: an anchor on A and one on B coincide.
//   C = pA - pB                       (3 rows, along the world axes e_i)
//   Ċ = vA + ωA×rA - vB - ωB×rB
//   J_i = (e_i, rA×e_i, -e_i, -rB×e_i)   local: rotational parts R⁻¹(r×e_i)
//   β = -C/h,  λ unbounded: a 'stable' constraint, block-solved as one 3x3 system (IV.2.2 item 2)
// Hinge, cone-twist and fixed joints start with these three rows (pointRows).
#pragma once

#include "physics/constraints/row.h"
#include "physics/model.h"

namespace substep {

// pA - pB [m]
Vec3 ballError(const Joint& j, const Pose& A, const Pose& B);
// The three anchor rows, shared by every joint that holds a point.
void pointRows(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly);

}  // namespace substep

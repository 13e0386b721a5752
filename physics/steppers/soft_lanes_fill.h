// What the soft step's lanes formulate their manifolds from (soft_lanes.h, ManifoldLanes): the
// one piece of the fill that reads the constraint set's definitions, here so that a test can
// formulate a group as the step does and compare it with the set's own rows.
#pragma once

#include "physics/constraints/constraint_set.h"
#include "physics/steppers/soft_lanes.h"

namespace substep::lanes {

// Lane l of `in` from manifold k of cs: everything formulateManifold(k) reads, the frame's fields
// (the world's, or with ContactFrame::Bodies the bodies' local ones) and the warm start's.
void gatherManifold(const ConstraintSet& cs, size_t k, int l, ManifoldLanes& in);
// Lane l's inverse masses in g, those of bodies A and B as the rows' M̌⁻¹J̌ᵀ take them (finishRow's
// scale is 1 under the soft step); zero in a lane not in use (`used` false).
void putMasses(Group& g, int l, const BodyMass& A, const BodyMass& B, bool used);
// The formulation constants of cs's last build, for sub-step hSub.
Formulation formulation(const ConstraintSet& cs, double hSub);
// Lane l of a vector's three lanes (a row's lin, angA or angB).
inline Vec3 laneVector(const Doubles* v, int l) { return Vec3(v[0].x[l], v[1].x[l], v[2].x[l]); }

}  // namespace substep::lanes

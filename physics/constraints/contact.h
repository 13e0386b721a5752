// Contact with Coulomb friction, the report's IV.3.1.1.
//
// Points a and b fixed on bodies A and B (arms σa, σb from the centres of mass), an axis n fixed
// on B (from B towards A) and the allowed penetration hi (the 'slop'):
//   C    = (pa - pb)·n + hi >= 0
//   Ċ    = (ṗa - ṗb)·n = n·vA + (σa×n)·ωA - n·vB - (σb×n)·ωB
//   J    = (n, σa×n, -n, -σb×n)                     local: rotational parts R⁻¹(σ×n)
//   β    = (-1/h) [(pa - pb)·n + hi]                 λn >= 0
// Friction: two rows along tangents t1, t2 of n, β = 0, |λt| <= μ λn (a box, not a cone).
// All three rows take their arms to the midpoint of pa and pb (see contact.cpp).
#pragma once

#include "physics/constraints/row.h"
#include "physics/math.h"

namespace substep {

struct ContactDef {
  int a = 0, b = 0;
  Vec3 localA = Vec3::Zero();  // σ̌a [m]
  Vec3 localB = Vec3::Zero();  // σ̌b [m]
  Vec3 localN = Vec3::UnitY(); // n in B's frame
  double mu = 0;               // friction coefficient
  double restitution = 0;
};

// (pa - pb)·n at the given poses: negative when penetrating [m].
double contactGap(const ContactDef& c, const Pose& A, const Pose& B);

// Fills rows[0] (normal) and rows[1], rows[2] (friction) at poses A, B for time step h.
// jacobianOnly keeps the rows' biases (A4/A5 update them by the report's rule instead).
void formulateContact(const ContactDef& c, const Pose& A, const Pose& B, double h, double slop, Row* rows,
                      bool jacobianOnly);

}  // namespace substep

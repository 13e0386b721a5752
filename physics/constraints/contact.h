// Contact: a normal row per contact point, as the report's IV.3.1.1 has it, and friction per
// manifold.
//
// Normal. Points a and b fixed on bodies A and B (arms σa, σb from the centres of mass), an
// axis n fixed on B (from B towards A) and the allowed penetration hi (the 'slop'):
//   C    = (pa - pb)·n + hi >= 0
//   Ċ    = (ṗa - ṗb)·n = n·vA + (σa×n)·ωA - n·vB - (σb×n)·ωB
//   J    = (n, σa×n, -n, -σb×n)                     local: rotational parts R⁻¹(σ×n)
//   β    = (-1/h) [(pa - pb)·n + hi]                 λn >= 0
//
// Friction (the report leaves it open). Per manifold, at the centroid c of its points: two
// rows on tangents t1, t2 of n and one on n itself (twist), β = 0,
//   |λt| <= μ Σλn,   |λtwist| <= μ r Σλn          (r: the points' mean distance from c)
// the way Havok and PhysX apply friction to a contact patch. Per-point friction gives a box on
// the ground eight tangent rows for three tangential degrees of freedom; Gauss-Seidel then winds
// up self-cancelling friction impulses that warm starting keeps and grows until the box walks
// (docs/algorithms.md).
#pragma once

#include "physics/constraints/row.h"
#include "physics/math.h"

namespace substep {

struct ContactDef {
  int a = 0, b = 0;
  Vec3 localA = Vec3::Zero();  // σ̌a [m]
  Vec3 localB = Vec3::Zero();  // σ̌b [m]
  Vec3 localN = Vec3::UnitY(); // n in B's frame
  // ContactFrame::World: the normal and the arms as the narrowphase found them, in the world; the
  // separation still comes from localA, localB at the current poses.
  bool worldFrame = false;
  Vec3 worldN = Vec3::UnitY();
  Vec3 armA = Vec3::Zero(), armB = Vec3::Zero();  // [m]
  int row = 0;                 // its normal row
  double restitution = 0;      // e of the pair
  double approach = 0;         // J̌v̌ at the step's start, before ext: < 0 when closing [m/s]
  double lastLambda = 0;       // the point's λ at the end of the last step, which warm starting takes [N s]
};

struct FrictionDef {
  int a = 0, b = 0;
  Vec3 localA = Vec3::Zero();  // the centroid of the manifold's points on A, in A's frame [m]
  Vec3 localB = Vec3::Zero();  // ... on B, in B's frame [m]
  Vec3 localN = Vec3::UnitY(); // n in B's frame
  bool worldFrame = false;     // ContactDef's: the normal and the centroid's arms kept in the world
  Vec3 worldN = Vec3::UnitY();
  Vec3 armA = Vec3::Zero(), armB = Vec3::Zero();  // to the centroid [m]
  double mu = 0;               // friction coefficient
  double radius = 0;           // mean distance of the points from the centroid [m]
  int row = 0;                 // its three rows: t1, t2, twist
  int firstNormal = 0, normalCount = 0;  // the manifold's normal rows (contiguous)
  int unit = -1;               // their contact block's SolveUnit, if they are one
  int firstNormalUnit = 0, frictionUnit = 0;  // the SolveUnits of its normal rows (1 or normalCount), of its friction
  Quat qB = Quat::Identity();  // B's orientation when formulated: warm-start impulses are kept in B's frame
  Vec3 lastImpulse = Vec3::Zero();  // the manifold's tangential impulse at the end of the last step, in B's frame [N s]
  double lastTwist = 0;             // ... and its twist [N m s]
};

// (pa - pb)·n at the given poses: negative when penetrating [m].
double contactGap(const ContactDef& c, const Frame& A, const Frame& B);

// A normal row apart at the step's start (C > 0, β < 0) is a speculative point (closing the gap at
// full speed); without speculative points (the report has none) it stays in the manifold but holds
// nothing until it touches (hi = λ = 0).
inline bool apartAndSpeculative(double bias, bool speculative) { return bias < 0 && speculative; }
inline void markApart(Row& row, bool speculative) {
  row.speculative = apartAndSpeculative(row.bias, speculative);
  if (row.bias < 0 && !speculative) row.hi = row.lambda = 0;
}

// The normal row at poses A, B for time step h. jacobianOnly keeps the bias (A4/A5 update it
// by the report's rule instead).
void formulateContact(const ContactDef& c, const Frame& A, const Frame& B, double h, double slop, Row& row,
                      bool jacobianOnly);
// The three friction rows of a manifold.
void formulateFriction(const FrictionDef& f, const Frame& A, const Frame& B, Row* rows, bool jacobianOnly);

// The tangential impulse λ1 t1 + λ2 t2 of friction rows formulated with B at qB, as a vector
// fixed in B (B's frame): how a warm-started impulse is carried, between steps and sub-steps.
Vec3 frictionImpulseInB(const Quat& qB, const Row* rows);
// ... of the tangent rows' impulses λ1, λ2 on their directions t1, t2 (their `lin`).
Vec3 frictionImpulseInB(const Quat& qB, double lambda1, const Vec3& t1, double lambda2, const Vec3& t2);
// ... and such an impulse projected on the tangents of friction rows formulated at B: whichever
// basis the normal now gets (tangentBasis switches at |n.x| = 1/√3), the impulse keeps its
// direction on B.
void carryFrictionImpulse(const Vec3& impulseInB, const Frame& B, Row* rows);

}  // namespace substep

// One row of the report's local Jacobian J̌ (section III.1) between two bodies, with what the
// iterative solvers precompute for it: its Jacobian numbers, M̌⁻¹J̌ᵀ and the effective mass.
// Translational parts are in the world frame; rotational parts in each body's frame (the
// report's R_j⁻¹ k), so they multiply the local angular velocity v̌ directly and the rotational
// inverse mass is the constant diagonal M̌⁻¹ = diag(1/I1, 1/I2, 1/I3).
#pragma once

#include "physics/math.h"

#include <limits>

namespace substep {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

struct BodyMass {
  double invMass = 0;           // [1/kg]
  Vec3 invI = Vec3::Zero();     // M̌⁻¹, rotational [1/(kg m^2)]
};

// Every row is built from the parts in parts.h (an axis or an angle part), so J̌ on B's translation
// is always minus J̌ on A's: one vector `lin` holds both, and M̌⁻¹J̌ᵀ's translational parts are the
// bodies' (scaled) inverse masses times it: 208 bytes a row, 264 with both halves stored. The
// arithmetic below is that of the two halves, term for term, so that (with κ = 1) every number
// is the same to the last bit as with both stored.
struct Row {
  int a = 0, b = 0;                                    // bodies
  Vec3 lin = Vec3::Zero();                             // J̌ on A's translation (world); on B's: -lin
  Vec3 angA = Vec3::Zero(), angB = Vec3::Zero();       // J̌ on A's and B's rotation, each in its body's frame
  Vec3 mAngA = Vec3::Zero(), mAngB = Vec3::Zero();     // M̌⁻¹J̌ᵀ, rotational: angular velocity change per unit impulse
  double mA = 0, mB = 0;                               // M̌⁻¹J̌ᵀ, translational: mA lin on A, -mB lin on B [1/kg]
  double effMass = 0;                                  // 1 / (J̌ M̌⁻¹ J̌ᵀ)
  double bias = 0;                                     // β [m/s or rad/s]
  double lo = -kInfinity, hi = kInfinity;              // bounds of λ; friction rows: ±μ, times Σλ of their normals
  int normalRow = -1;                                  // friction rows: the first normal row of their manifold
  int normalCount = 0;                                 // ... and how many (contiguous) rows bound them
  bool velocityLevel = false;                          // friction, motors: no position C behind β, so the
                                                       // bias update rule (proc4:16) does not apply
  bool velocityTarget = false;                         // motor: β is a target velocity (solved with κ = τ = 1
                                                       // unless SolverSettings::motorUnscaled is off)
  bool speculative = false;                            // contact normal apart at the step's start (C > 0): while
                                                       // β < 0 it closes the gap at full speed, not τ of it
  bool pushed = false;                                 // λ was positive during this step (restitution)
  double split = 0;                                    // split impulse: the part of β moved to the position solve
  double lambda = 0;                                   // accumulated impulse [N s or N m s]
};

// Row{}'s values of the fields a contact's formulation (formulateContact or formulateFriction, then
// finishRow) does not write: all that build() resets of a row it formulates over last step's.
inline void resetRowState(Row& r) {
  r.normalRow = -1;
  r.normalCount = 0;
  r.velocityLevel = r.velocityTarget = r.speculative = r.pushed = false;
  r.split = 0;
  r.lambda = 0;
}
// r = Row{}, field by field (no zero-filled temporary). A new field must be reset here too, and in
// resetRowState unless every formulation writes it.
static_assert(sizeof(Row) == 208, "a field was added to Row: reset it in resetRow");
inline void resetRow(Row& r) {
  r.a = r.b = 0;
  r.lin.setZero();
  r.angA.setZero();
  r.angB.setZero();
  r.mAngA.setZero();
  r.mAngB.setZero();
  r.mA = r.mB = 0;
  r.effMass = 0;
  r.bias = 0;
  r.lo = -kInfinity;
  r.hi = kInfinity;
  resetRowState(r);
}

// Rows solved together: the report's "block constraint x" of proc3:10. A single row with its
// bounds; an unbounded 'stable' block (2 or 3 rows), solved by inverting its block of
// Γ = J̌M̌⁻¹J̌ᵀ (IV.2.2 item 2); or a contact block, the normal rows of one manifold (up to 4),
// solved as the small MLCP it is (λ >= 0). A manifold's three friction rows are a Friction unit:
// solved row after row as three singles, with their two bodies' velocities and the normals' Σλ
// that bounds them read once, and each row's J̌v̌ updated from the earlier rows' Δλ by their
// coupling (FrictionCoupling) instead of from the velocities they changed.
struct SolveUnit {
  enum Kind : unsigned char { Single, Stable, Contact, Friction };
  int first = 0;
  int size = 1;
  Kind kind = Single;
  int block = -1;  // its BlockData
};

struct BlockData {
  // Not zero-initialised: ConstraintSet::finish writes both whole before any use (a deferred lane
  // group's block, ConstraintSet::laneBlock, K alone: nothing reads its K⁻¹).
  Eigen::Matrix4d K;     // the block of Γ (unscaled M̌⁻¹)
  Eigen::Matrix4d invK;  // its inverse (contact blocks: of K regularised)
  int lastMask = -1;  // contact blocks: the proper active set that fitted last (bit i: row i pushes)
};

// A Friction unit's couplings: how its later rows' J̌v̌ move per unit Δλ of its earlier ones,
// J̌ᵢ (M̌⁻¹J̌ⱼᵀ as the rows apply it, scaled by κ under A5). Gauss-Seidel over the three rows is
// then the same arithmetic, up to rounding, with the chain from one row's Δλ to the next row's
// J̌v̌ one product long instead of a velocity update and a twelve-term dot product.
struct FrictionCoupling {
  double g10 = 0, g20 = 0, g21 = 0;
};

// J̌ᵢ M̌⁻¹J̌ⱼᵀ of two rows on the same two bodies, with row j's (scaled) M̌⁻¹J̌ᵀ.
inline double coupling(const Row& i, const Row& j) {
  return i.lin.dot(j.mA * j.lin) + i.angA.dot(j.mAngA) + i.lin.dot(j.mB * j.lin) + i.angB.dot(j.mAngB);
}

// A manifold's three friction rows' couplings (rows finished).
inline FrictionCoupling frictionCoupling(const Row* r) {
  return {coupling(r[1], r[0]), coupling(r[2], r[0]), coupling(r[2], r[1])};
}

// Σλ of a friction row's normal rows: what its bounds scale with.
inline double normalImpulse(const Row& r, const Row* rows) {
  double s = 0;
  for (int k = 0; k < r.normalCount; ++k) s += rows[r.normalRow + k].lambda;
  return s;
}

// J̌ v̌ of a row for velocities v (world linear) and w (body-frame angular).
__attribute__((always_inline)) inline double rowVelocity(const Row& r, const Vec3& vA, const Vec3& wA, const Vec3& vB,
                                                         const Vec3& wB) {
  return r.lin.dot(vA) + r.angA.dot(wA) - r.lin.dot(vB) + r.angB.dot(wB);
}
inline double rowVelocity(const Row& r, const Vec3* v, const Vec3* w) {
  return rowVelocity(r, v[r.a], w[r.a], v[r.b], w[r.b]);
}

// v̌ += M̌⁻¹J̌ᵀ dλ.
// Always inlined: it is the innermost work of every sweep, a call per row otherwise.
// Component by component, the same arithmetic as Eigen's vA += dl * (r.mA * r.lin) and so on:
// Eigen's += is a function of its own, which link-time optimisation has left out of line in the
// sweep once other code used it more (a fifth more of the sweep's time, docs/benchmarks.md).
__attribute__((always_inline)) inline void applyImpulse(const Row& r, double dl, Vec3& vA, Vec3& wA, Vec3& vB,
                                                        Vec3& wB) {
  for (int i = 0; i < 3; ++i) vA[i] += dl * (r.mA * r.lin[i]);
  for (int i = 0; i < 3; ++i) wA[i] += dl * r.mAngA[i];
  for (int i = 0; i < 3; ++i) vB[i] -= dl * (r.mB * r.lin[i]);
  for (int i = 0; i < 3; ++i) wB[i] += dl * r.mAngB[i];
}
// Velocities back to the row's bodies that move. A static (or sleeping) body's M̌⁻¹ is zero, so
// its velocity would come back unchanged: left unwritten, it is read-only to the solve, and
// islands that share it (the ground) can be solved on different threads.
__attribute__((always_inline)) inline void storeMoving(const Row& r, const Vec3& vA, const Vec3& wA, const Vec3& vB,
                                                       const Vec3& wB, Vec3* v, Vec3* w) {
  if (r.mA != 0) v[r.a] = vA, w[r.a] = wA;
  if (r.mB != 0) v[r.b] = vB, w[r.b] = wB;
}
__attribute__((always_inline)) inline void applyImpulse(const Row& r, double dl, Vec3* v, Vec3* w) {
  Vec3 vA = v[r.a], wA = w[r.a], vB = v[r.b], wB = w[r.b];
  applyImpulse(r, dl, vA, wA, vB, wB);
  storeMoving(r, vA, wA, vB, wB, v, w);
}

// Fills M̌⁻¹J̌ᵀ (scaled by applyScale: the report's boxed κM̌⁻¹ in A5, else 1) and the effective
// mass, which always uses the unscaled M̌⁻¹ (see docs/algorithms.md, A5 derivation).
inline void finishRow(Row& r, const BodyMass& A, const BodyMass& B, double applyScale = 1.0) {
  const Vec3 mAngA = A.invI.cwiseProduct(r.angA), mAngB = B.invI.cwiseProduct(r.angB);
  const double k = r.lin.dot(A.invMass * r.lin) + r.angA.dot(mAngA) + r.lin.dot(B.invMass * r.lin) + r.angB.dot(mAngB);
  r.effMass = k > 0 ? 1.0 / k : 0.0;
  r.mA = applyScale * A.invMass;
  r.mB = applyScale * B.invMass;
  r.mAngA = applyScale * mAngA;
  r.mAngB = applyScale * mAngB;
}

// Γ entry between rows r and s: J̌_r M̌⁻¹ J̌_sᵀ (zero unless they share a body).
inline double gammaEntry(const Row& r, const Row& s, const BodyMass* m) {
  double g = 0;
  // sr, ss: the sign of each row's translational part on that body (+ on A, - on B).
  auto body = [&](int br, double sr, const Vec3& ar, int bs, double ss, const Vec3& as) {
    if (br != bs) return;
    const BodyMass& M = m[br];
    g += sr * ss * M.invMass * r.lin.dot(s.lin) + ar.dot(M.invI.cwiseProduct(as));
  };
  body(r.a, 1, r.angA, s.a, 1, s.angA);
  body(r.a, 1, r.angA, s.b, -1, s.angB);
  body(r.b, -1, r.angB, s.a, 1, s.angA);
  body(r.b, -1, r.angB, s.b, -1, s.angB);
  return g;
}

}  // namespace substep

// One row of the report's local Jacobian J̌ (section III.1) between two bodies, with what the
// iterative solvers precompute for it, in flat arrays: 12 Jacobian numbers, M̌⁻¹J̌ᵀ and the
// effective mass. Translational parts are in the world frame; rotational parts in each body's
// frame (the report's R_j⁻¹ k), so they multiply the local angular velocity v̌ directly and the
// rotational inverse mass is the constant diagonal M̌⁻¹ = diag(1/I1, 1/I2, 1/I3).
#pragma once

#include "physics/math.h"

#include <limits>

namespace substep {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

struct BodyMass {
  double invMass = 0;           // [1/kg]
  Vec3 invI = Vec3::Zero();     // M̌⁻¹, rotational [1/(kg m^2)]
};

struct Row {
  int a = 0, b = 0;                                    // bodies
  Vec3 linA = Vec3::Zero(), angA = Vec3::Zero();       // J̌ on A: world translation, A-frame rotation
  Vec3 linB = Vec3::Zero(), angB = Vec3::Zero();       // J̌ on B
  Vec3 mLinA = Vec3::Zero(), mAngA = Vec3::Zero();     // M̌⁻¹J̌ᵀ on A: velocity change per unit impulse
  Vec3 mLinB = Vec3::Zero(), mAngB = Vec3::Zero();     // M̌⁻¹J̌ᵀ on B
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

// Rows solved together: the report's "block constraint x" of proc3:10. A single row with its
// bounds; an unbounded 'stable' block (2 or 3 rows), solved by inverting its block of
// Γ = J̌M̌⁻¹J̌ᵀ (IV.2.2 item 2); or a contact block, the normal rows of one manifold (up to 4),
// solved as the small MLCP it is (λ >= 0). A manifold's three friction rows are a Friction unit:
// solved row after row exactly as three singles, with their two bodies' velocities and the
// normals' Σλ that bounds them read once.
struct SolveUnit {
  enum Kind : unsigned char { Single, Stable, Contact, Friction };
  int first = 0;
  int size = 1;
  Kind kind = Single;
  int block = -1;  // its BlockData
};

struct BlockData {
  Eigen::Matrix4d K = Eigen::Matrix4d::Zero();     // the block of Γ (unscaled M̌⁻¹)
  Eigen::Matrix4d invK = Eigen::Matrix4d::Zero();  // its inverse (contact blocks: of K regularised)
  int lastMask = -1;  // contact blocks: the proper active set that fitted last (bit i: row i pushes)
};

// Σλ of a friction row's normal rows: what its bounds scale with.
inline double normalImpulse(const Row& r, const Row* rows) {
  double s = 0;
  for (int k = 0; k < r.normalCount; ++k) s += rows[r.normalRow + k].lambda;
  return s;
}

// J̌ v̌ of a row for velocities v (world linear) and w (body-frame angular).
inline double rowVelocity(const Row& r, const Vec3* v, const Vec3* w) {
  return r.linA.dot(v[r.a]) + r.angA.dot(w[r.a]) + r.linB.dot(v[r.b]) + r.angB.dot(w[r.b]);
}

// v̌ += M̌⁻¹J̌ᵀ dλ.
inline void applyImpulse(const Row& r, double dl, Vec3* v, Vec3* w) {
  v[r.a] += dl * r.mLinA;
  w[r.a] += dl * r.mAngA;
  v[r.b] += dl * r.mLinB;
  w[r.b] += dl * r.mAngB;
}

// Fills M̌⁻¹J̌ᵀ (scaled by applyScale: the report's boxed κM̌⁻¹ in A5, else 1) and the effective
// mass, which always uses the unscaled M̌⁻¹ (see docs/algorithms.md, A5 derivation).
inline void finishRow(Row& r, const BodyMass& A, const BodyMass& B, double applyScale = 1.0) {
  const Vec3 mLinA = A.invMass * r.linA, mAngA = A.invI.cwiseProduct(r.angA);
  const Vec3 mLinB = B.invMass * r.linB, mAngB = B.invI.cwiseProduct(r.angB);
  const double k = r.linA.dot(mLinA) + r.angA.dot(mAngA) + r.linB.dot(mLinB) + r.angB.dot(mAngB);
  r.effMass = k > 0 ? 1.0 / k : 0.0;
  r.mLinA = applyScale * mLinA;
  r.mAngA = applyScale * mAngA;
  r.mLinB = applyScale * mLinB;
  r.mAngB = applyScale * mAngB;
}

// Γ entry between rows r and s: J̌_r M̌⁻¹ J̌_sᵀ (zero unless they share a body).
inline double gammaEntry(const Row& r, const Row& s, const BodyMass* m) {
  double g = 0;
  auto body = [&](int br, const Vec3& lr, const Vec3& ar, int bs, const Vec3& ls, const Vec3& as) {
    if (br != bs) return;
    const BodyMass& M = m[br];
    g += M.invMass * lr.dot(ls) + ar.dot(M.invI.cwiseProduct(as));
  };
  body(r.a, r.linA, r.angA, s.a, s.linA, s.angA);
  body(r.a, r.linA, r.angA, s.b, s.linB, s.angB);
  body(r.b, r.linB, r.angB, s.a, s.linA, s.angA);
  body(r.b, r.linB, r.angB, s.b, s.linB, s.angB);
  return g;
}

}  // namespace substep

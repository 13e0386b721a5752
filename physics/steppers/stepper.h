// s3 and s4: one stepper per algorithm of the report, behind one interface.
//   a1_direct.cpp          Algorithm 1, essential stepping with a direct MLCP solve
//   a2_pgs.cpp             Algorithm 2, essential stepping, iterative (projected Gauss-Seidel, SOR)
//   a3_havok_conceptual.cpp, a4_havok_approximative.cpp, a5_havok_actual.cpp: sub-stepping
#pragma once

#include "physics/constraints/constraint_set.h"
#include "physics/model.h"
#include "physics/settings.h"
#include "physics/state.h"

#include <memory>
#include <vector>

namespace substep {

struct StepStats {
  int iterations = 0;      // sweeps done (A2: until converged or capped; A3-A5: n·m)
  double residual = 0;     // A1: MLCP residual [m/s]; A2: largest row velocity change in the last sweep
  int rows = 0;
};

// What a stepper works on during one step. The world fills it in s1/s2.
struct StepContext {
  const Model* model = nullptr;
  const SolverSettings* settings = nullptr;
  State* state = nullptr;
  ConstraintSet* constraints = nullptr;
  std::vector<BodyMass> mass;      // per body; zero for static bodies
  std::vector<Pose> poses;         // coordinates at the step's start
  std::vector<Vec3> v, w;          // solver velocities: linear (world), angular (body frame, v̌)
  // The sub-step velocities v^1..v^n the coordinates are stepped with (s4): index j*bodies + i.
  std::vector<Vec3> subV, subW;
  StepStats stats;

  double h() const { return settings->dt; }
  int n() const { return settings->substeps; }
  size_t bodies() const { return mass.size(); }
};

class Stepper {
 public:
  virtual ~Stepper() = default;
  virtual void stepVelocities(StepContext& c) = 0;   // s3
  virtual void stepCoordinates(StepContext& c) = 0;  // s4
};

std::unique_ptr<Stepper> makeStepper(Algorithm a);

// --- shared pieces ---------------------------------------------------------------------------

// Adds ext, the velocity the external forces give in time dt (gravity only: no gyroscopic term,
// as the report's ext), to every dynamic body.
void addExternal(StepContext& c, double dt);

// Applies every row's current λ to the velocities (warm starting): v̌ += M̌⁻¹J̌ᵀλ.
void applyRowImpulses(ConstraintSet& cs, std::vector<Vec3>& v, std::vector<Vec3>& w);

// One Gauss-Seidel sweep over all solve units. For each unit
//   Δλ = m_eff (cBias β - cVel J̌ v̌),  λ <- proj(λ + Δλ),  v̌ += M̌⁻¹J̌ᵀ Δλ
// with (cBias, cVel) = (ω, ω) for A2's PSOR, (τ, κ) for A3/A4, (1, 1) for A5 (factors baked in).
// Rows with a velocity target (motors) use (cBiasTarget, cVelTarget). Returns the largest
// velocity change of a row, |Δλ| / m_eff [m/s or rad/s].
double sweep(ConstraintSet& cs, std::vector<Vec3>& v, std::vector<Vec3>& w, double cBias, double cVel,
             double cBiasTarget, double cVelTarget);

// How sub-step rotations combine into the step's orientation change.
enum class RotationRule {
  Product,  // A3 (proc3:19): rq ∘ R_q(h/n rv̌^1) ∘ ... ∘ R_q(h/n rv̌^n), exact
  Summed,   // A4/A5 (proc4:20): rq ∘ R_q(Σ h/n rv̌^k), first order (IV.3.3, section V)
};
// q stepped by n sub-step angular velocities w[0], w[stride], ... (body frame) of length dt each.
Quat stepRotation(const Quat& q, const Vec3* w, size_t stride, int n, double dt, RotationRule rule);

// s4 for A1/A2 (proc1:7-8): tq' = tq + h tv',  rq' = R_q(h rv') ∘ rq with rv' in the world frame.
void stepCoordinatesEssential(StepContext& c);
// s4 for A3-A5 (proc3:18-19, proc4:19-20): tq' = tq + Σ h/n tv̌^k and the rotation by `rule`.
void stepCoordinatesSubStepped(StepContext& c, RotationRule rule);

// Records the solver velocities as sub-step j's (0-based).
void recordSubStep(StepContext& c, int j);

}  // namespace substep

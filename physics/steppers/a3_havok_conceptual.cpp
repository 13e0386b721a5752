// Algorithm 3, Havok stepping, conceptual (report IV.2, proc3): n sub-steps of h/n, each solving
// the scaled problem with m micro-iterations, the constraints re-formulated exactly in between.
//   proc3:4   v̌⁰ = v̌, J̌¹ = J̌, β¹ = β(h/n)                  (s2 formulated with h/n)
//   proc3:6   v̌ʲ = v̌ʲ⁻¹ + ext                             ext = h/n g
//   proc3:11  solve J̌_x(κ v̌ + M̌⁻¹J̌ᵀλ) = τ β_x : C(λ_x)     per block or row, m times
//   proc3:15  J̌ʲ⁺¹, βʲ⁺¹ from the coordinates at t + j h/n  (anchors move with their bodies)
//   proc3:18  tq' = tq + Σ h/n tv̌ᵏ
//   proc3:19  rq' = rq ∘ R_q(h/n rv̌¹) ∘ ... ∘ R_q(h/n rv̌ⁿ)   exact, right-multiplied: v̌ is local
// Motors are solved with κ = τ = 1 (motor.cpp).
#include "physics/steppers/stepper.h"

namespace substep {

namespace {

class HavokConceptualStepper final : public Stepper {
 public:
  void stepVelocities(StepContext& c) override {
    ConstraintSet& cs = *c.constraints;
    const int n = c.n(), m = c.settings->iterations;
    const double dt = c.h() / n, kappa = c.settings->kappa, tau = c.settings->tau;
    c.stats = StepStats{};
    c.stats.rows = static_cast<int>(cs.rows.size());
    splitPositionErrors(c);
    beginSubSteps(c);
    for (int j = 0; j < n; ++j) {
      addExternal(c, dt);
      startSubStepImpulses(c, j);
      for (int i = 0; i < m && !cs.rows.empty(); ++i) c.stats.residual = sweep(cs, c.v, c.w, tau, kappa, 1, 1);
      recordSubStep(c, j);
      if (j + 1 < n) {
        advanceSubPoses(c, j, RotationRule::Product);
        cs.reformulate(c.subPoses, c.mass, dt, ConstraintSet::Refresh::All, 1.0);
      }
    }
    c.stats.iterations = n * m;
    solvePositionErrors(c, n * m, 1.0);
  }

  void stepCoordinates(StepContext& c) override { stepCoordinatesSubStepped(c, RotationRule::Product); }
};

}  // namespace

std::unique_ptr<Stepper> makeHavokConceptualStepper() { return std::make_unique<HavokConceptualStepper>(); }

}  // namespace substep

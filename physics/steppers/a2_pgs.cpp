// Algorithm 2, essential stepping, iterative (report IV.1, proc2): projected Gauss-Seidel with
// successive over-relaxation, row by row, until converged or capped.
//   proc2:4   v̂'⁰ = v + ext
//   proc2:6   while the largest row velocity change > tolerance and sweeps < cap
//   proc2:8   for each row x: solve J_x(v̂'◇ + M_x⁻¹J_xᵀλ) = β_x : C(λ_x) for the increment δ,
//   proc2:11  relax: v̂'◇⁺¹ = (1 - ω) v̂'◇ + ω (v̂'◇ + δ) = v̂'◇ + ωδ
// The listing's proc2:11 reads (1-ω)v̂ + ωδ, which mixes a velocity with an increment; the line
// above is the consistent reading (PSOR on λ, projected on the bounds), see docs/algorithms.md.
#include "physics/steppers/stepper.h"

namespace substep {

namespace {

class PgsStepper final : public Stepper {
 public:
  void stepVelocities(StepContext& c) override {
    ConstraintSet& cs = *c.constraints;
    splitPositionErrors(c);
    addExternal(c, c.h());
    if (c.settings->warmStart) applyRowImpulses(cs, c.v, c.w);
    const double omega = c.settings->omega;
    c.stats = StepStats{};
    c.stats.rows = static_cast<int>(cs.rows.size());
    if (cs.rows.empty()) return;
    for (int it = 1; it <= c.settings->iterations; ++it) {
      c.stats.residual = sweep(cs, c.v, c.w, SweepScales::psor(omega));
      c.stats.iterations = it;
      if (c.stats.residual <= c.settings->tolerance) break;
    }
    applyRestitution(c, c.v.data(), c.w.data(), 1.0);
    solvePositionErrors(c, c.stats.iterations, 1.0);
  }

  void stepCoordinates(StepContext& c) override { stepCoordinatesEssential(c); }
};

}  // namespace

std::unique_ptr<Stepper> makePgsStepper() { return std::make_unique<PgsStepper>(); }

}  // namespace substep

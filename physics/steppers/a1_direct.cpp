// Algorithm 1, essential stepping (report IV.1, proc1): one direct solve of the MLCP per step.
//   proc1:4  solve J̌(v̌ + ext + M̌⁻¹J̌ᵀλ) = β : C(λ)      (Γλ = β - J̌(v̌ + ext) + w)
//   proc1:5  v̌' = v̌ + ext + δ
//   proc1:7  tq' = tq + h tv'
//   proc1:8  rq' = R_q(h rv') ∘ rq
// Γ is formed densely, so A1 accepts at most settings.directMaxRows rows.
#include "physics/steppers/mlcp_direct.h"
#include "physics/steppers/stepper.h"
#include "physics/world.h"

#include <stdexcept>
#include <string>

namespace substep {

namespace {

class DirectStepper final : public Stepper {
 public:
  void stepVelocities(StepContext& c) override {
    ConstraintSet& cs = *c.constraints;
    addExternal(c, c.h());  // v̌ + ext
    const int n = static_cast<int>(cs.rows.size());
    c.stats = StepStats{};
    c.stats.rows = n;
    if (n == 0) return;
    if (n > c.settings->directMaxRows)
      throw Refused("a1 solves the MLCP with a dense " + std::to_string(n) + "x" + std::to_string(n) +
                               " matrix, more than its limit of " + std::to_string(c.settings->directMaxRows) +
                               " rows; use --algo a2..a5 for a scene this large");
    assembleMLCP(cs.rows, c.mass, c.v.data(), c.w.data(), p_);
    const DirectResult res = solveDirect(p_, lambda_, c.settings->directWorkBudget);
    if (!res.ok)
      throw Refused("a1: the direct MLCP solver found no answer to a " + std::to_string(n) +
                               "-row problem within its work budget; use --algo a2..a5 for this scene");
    c.stats.directMethod = res.method;
    c.stats.residual = res.residual;
    for (int i = 0; i < n; ++i) {
      Row& r = cs.rows[static_cast<size_t>(i)];
      r.lambda = lambda_[static_cast<size_t>(i)];
      r.pushed = r.lambda > 0;
      applyImpulse(r, r.lambda, c.v.data(), c.w.data());  // v̌' = v̌ + ext + δ
    }
    applyRestitution(c, c.v.data(), c.w.data(), 1.0);
  }

  void stepCoordinates(StepContext& c) override { stepCoordinatesEssential(c); }

 private:
  DenseMLCP p_;
  std::vector<double> lambda_;
};

}  // namespace

std::unique_ptr<Stepper> makeDirectStepper() { return std::make_unique<DirectStepper>(); }

}  // namespace substep

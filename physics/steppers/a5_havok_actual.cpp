// Algorithm 5, Havok stepping, actual (report IV.4, proc5): A4 refactored so that τ and κ are
// baked in and the bias is a constant, with the listing's inconsistencies resolved as derived in
// docs/algorithms.md ("A5 as a refactoring of A4"). Names as Havok's code has them:
//   'Velocity'     ŵ = v̌ + š          the shifted velocity the rows are solved on
//   'SumVelocity'  š = (τ/κ) Σ_{k<j} v̌ᵏ
//   β̄ = (τ/κ) β                        constant over the sub-steps (IV.4.1's Jacobian approximation)
//   M̄⁻¹ = κ M̌⁻¹,  λ̄ = λ/κ             (the rows' M̌⁻¹J̌ᵀ are scaled by κ in s2)
// Per row: λ̄ += m_eff (β̄ - J̌ŵ) with m_eff = 1/(J̌M̌⁻¹J̌ᵀ) (unscaled!), projected; ŵ += M̄⁻¹J̌ᵀΔλ̄.
//   proc5:5   š¹ = 0, ŵ¹ = v̌⁰ + ext       (the listing's w̌⁰ = v̌⁰ skips the first ext)
//   proc5:15  v̌ʲ = ŵʲ - šʲ
//   proc5:16  šʲ⁺¹ = šʲ + (τ/κ) v̌ʲ
//   proc5:17-18  ŵʲ⁺¹ = v̌ʲ + ext + šʲ⁺¹   (only between sub-steps)
//   proc5:20-22  as proc4:18-20 (summed rotations)
// Velocity-level rows undo the baked-in update (IV.3.1.4): their bias becomes β + J̌š, so they
// solve J̌v̌ = β: motors their target speed (with κ = 1), friction rows 0 (with κ).
#include "physics/steppers/stepper.h"

namespace substep {

namespace {

class HavokActualStepper final : public Stepper {
 public:
  void stepVelocities(StepContext& c) override {
    ConstraintSet& cs = *c.constraints;
    const int n = c.n(), m = c.settings->iterations;
    const double dt = c.h() / n, kappa = c.settings->kappa, tau = c.settings->tau;
    const double ratio = tau / kappa;
    const size_t nb = c.bodies();
    c.stats = StepStats{};
    c.stats.rows = static_cast<int>(cs.rows.size());

    splitPositionErrors(c);
    // The boxed quantities (IV.4.2): β̄ = (τ/κ)β, bounds of λ̄ = bounds of λ over κ. Velocity-level
    // rows (friction: 0, motors: their speed) keep their β and take back the SumVelocity term.
    target_.clear();
    for (size_t k = 0; k < cs.rows.size(); ++k) {
      Row& r = cs.rows[k];
      if (r.velocityLevel) target_.emplace_back(k, r.velocityTarget ? r.bias : 0.0);
      if (r.velocityTarget) continue;
      r.bias *= ratio;
      if (r.normalRow < 0) {  // friction bounds are μ times the normal's λ̄ already
        r.lo /= kappa;
        r.hi /= kappa;
      }
      r.lambda /= kappa;  // warm-started impulses, as λ̄
    }
    sumV_.assign(nb, Vec3::Zero());
    sumW_.assign(nb, Vec3::Zero());
    beginSubSteps(c);
    addExternal(c, dt);  // ŵ¹ = v̌⁰ + ext (š¹ = 0)
    for (int j = 0; j < n; ++j) {
      startSubStepImpulses(c, j);
      for (const auto& [k, speed] : target_) {
        Row& r = cs.rows[k];
        r.bias = speed + rowVelocity(r, sumV_.data(), sumW_.data());
      }
      for (int i = 0; i < m && !cs.rows.empty(); ++i) c.stats.residual = sweep(cs, c.v, c.w, 1, 1, 1, 1);
      // v̌ʲ = ŵʲ - šʲ, recorded for s4; then šʲ⁺¹ and ŵʲ⁺¹.
      for (size_t i = 0; i < nb; ++i) {
        const Vec3 v = c.v[i] - sumV_[i], w = c.w[i] - sumW_[i];
        c.subV[static_cast<size_t>(j) * nb + i] = v;
        c.subW[static_cast<size_t>(j) * nb + i] = w;
        sumV_[i] += ratio * v;
        sumW_[i] += ratio * w;
      }
      if (j + 1 < n) {
        const Vec3 ext = dt * c.model->gravity;
        for (size_t i = 0; i < nb; ++i) {
          if (c.model->bodies[i].isStatic) continue;
          c.v[i] = c.subV[static_cast<size_t>(j) * nb + i] + ext + sumV_[i];
          c.w[i] = c.subW[static_cast<size_t>(j) * nb + i] + sumW_[i];
        }
        if (!cs.joints.empty()) {
          advanceSubPoses(c, j, RotationRule::Summed);
          cs.reformulate(c.subPoses, c.mass, dt, ConstraintSet::Refresh::JointJacobians, kappa);
        }
      }
    }
    c.stats.iterations = n * m;
    solvePositionErrors(c, n * m, kappa);  // rows apply κM̌⁻¹J̌ᵀ; the split is of β, not β̄
    for (Row& r : cs.rows)
      if (!r.velocityTarget) r.lambda *= kappa;  // kept as λ, for warm starting and overlays
  }

  void stepCoordinates(StepContext& c) override { stepCoordinatesSubStepped(c, RotationRule::Summed); }

 private:
  std::vector<std::pair<size_t, double>> target_;  // velocity-level rows and their β (motors: target speed)
  std::vector<Vec3> sumV_, sumW_;                   // 'SumVelocity' š, linear and angular
};

}  // namespace

std::unique_ptr<Stepper> makeHavokActualStepper() { return std::make_unique<HavokActualStepper>(); }

}  // namespace substep

// Algorithm 4, Havok stepping, approximative (report IV.3, proc4): A3 with three approximations.
//   proc4:15  J̌ʲ⁺¹: recomputed for joints from the coordinates at t + j h/n (stepped by the
//             summed rotation), held for contacts (IV.3.2; n ≈ n' makes a contact's J̌ constant)
//   proc4:16  βʲ⁺¹ = βʲ - J̌ʲ v̌ʲ   (IV.3.1: the bias update rule, first order), every row but
//             motors, which keep their target velocity (IV.3.1.4)
//   proc4:20  rq' = rq ∘ R_q(Σ h/n rv̌ᵏ)   (IV.3.3: summed rotations, first order)
// Otherwise as A3: ext per sub-step, m micro-iterations of J̌_x(κv̌ + M̌⁻¹J̌ᵀλ) = τβ_x.
#include "physics/steppers/stepper.h"

namespace substep {

namespace {

class HavokApproximativeStepper final : public Stepper {
 public:
  void stepVelocities(StepContext& c) override {
    c.rowsHeld = c.constraints->joints.empty();  // contacts keep J̌ over the step (proc4:16 updates β only)
    stepVelocitiesScaled(c, [&c](int j) {
      ConstraintSet& cs = *c.constraints;
      updateBiases(cs, c.v, c.w);  // proc4:16, with J̌ʲ, before the joints' J̌ is recomputed
      if (cs.joints.empty()) return;
      advanceSubPoses(c, j, RotationRule::Summed);  // proc4:15, joints only
      cs.reformulate(c.subPoses, c.mass, c.h() / c.n(), ConstraintSet::Reformulation::JointJacobians, 1.0);
    });
  }

  void stepCoordinates(StepContext& c) override { stepCoordinatesSubStepped(c, RotationRule::Summed); }
};

}  // namespace

std::unique_ptr<Stepper> makeHavokApproximativeStepper() { return std::make_unique<HavokApproximativeStepper>(); }

}  // namespace substep

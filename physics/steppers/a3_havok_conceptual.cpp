// Algorithm 3, Havok stepping, conceptual (report IV.2, proc3): n sub-steps of h/n, each solving
// the scaled problem with m micro-iterations, the constraints re-formulated exactly in between.
//   proc3:4   v̌⁰ = v̌, J̌¹ = J̌, β¹ = β(h/n)                  (s2 formulated with h/n)
//   proc3:6   v̌ʲ = v̌ʲ⁻¹ + ext                             ext = h/n g
//   proc3:11  solve J̌_x(κ v̌ + M̌⁻¹J̌ᵀλ) = τ β_x : C(λ_x)     per block or row, m times
//   proc3:15  J̌ʲ⁺¹, βʲ⁺¹ from the coordinates at t + j h/n  (anchors move with their bodies)
//   proc3:18  tq' = tq + Σ h/n tv̌ᵏ
//   proc3:19  rq' = rq ∘ R_q(h/n rv̌¹) ∘ ... ∘ R_q(h/n rv̌ⁿ)   exact, right-multiplied: v̌ is local
// Motors are solved with κ = τ = 1 (motor.cpp).
//
// For the tests that take A4 - A3 and A5 - A4 apart, the same stepper can make each of their
// approximations on its own (Approximations, stepper.h); with none it is A3 as above.
#include "physics/constraints/contact.h"
#include "physics/steppers/stepper.h"

namespace substep {

namespace {

class HavokConceptualStepper final : public Stepper {
 public:
  explicit HavokConceptualStepper(const Approximations& a) : a_(a) {}

  void stepVelocities(StepContext& c) override {
    if (a_.none()) {
      c.rowsHeld = false;  // every row re-formulated between sub-steps
      stepVelocitiesScaled(c, [&c](int j) {  // proc3:15, exactly, from the coordinates at t + (j+1) h/n
        advanceSubPoses(c, j, RotationRule::Product);
        c.constraints->reformulate(c.subPoses, c.mass, c.h() / c.n(), ConstraintSet::Reformulation::Everything, 1.0);
      });
      return;
    }
    c.rowsHeld = a_.holdJacobians && c.constraints->joints.empty();  // as A4
    if (a_.bias == BiasRule::UpdateOneJacobian) {
      const ConstraintSet& cs = *c.constraints;
      first_.resize(cs.rows.size());
      for (size_t k = 0; k < cs.rows.size(); ++k) first_[k] = cs.rows[k].bias;  // β¹
      sumV_.assign(c.bodies(), Vec3::Zero());
      sumW_.assign(c.bodies(), Vec3::Zero());
    }
    stepVelocitiesScaled(c, [this, &c](int j) { between(c, j); });
  }

  void stepCoordinates(StepContext& c) override { stepCoordinatesSubStepped(c, rule()); }

 private:
  RotationRule rule() const { return a_.summedRotation ? RotationRule::Summed : RotationRule::Product; }

  // proc3:15 with the chosen approximations: J̌ʲ⁺¹ (proc4:15) and βʲ⁺¹ (proc4:16 or IV.4.1) after
  // sub-step j, at the coordinates stepped by rule() (proc4:20).
  void between(StepContext& c, int j) {
    ConstraintSet& cs = *c.constraints;
    const double dt = c.h() / c.n();
    // βʲ - J̌ʲv̌ʲ needs J̌ʲ, so it is taken before any row is re-formulated.
    if (a_.bias == BiasRule::Update) {
      updated_.resize(cs.rows.size());
      for (size_t k = 0; k < cs.rows.size(); ++k)
        updated_[k] = cs.rows[k].bias - rowVelocity(cs.rows[k], c.v.data(), c.w.data());
    } else if (a_.bias == BiasRule::UpdateOneJacobian) {
      for (size_t i = 0; i < c.bodies(); ++i) sumV_[i] += c.v[i], sumW_[i] += c.w[i];  // Σ_{k<=j} v̌ᵏ
    }
    advanceSubPoses(c, j, rule());
    if (a_.holdJacobians) {
      // IV.3.2: contacts keep J̌¹ (n ≈ n'); joints are re-formulated (their β too: set below if
      // the bias is updated instead).
      cs.reformulate(c.subPoses, c.mass, dt, ConstraintSet::Reformulation::JointRows, 1.0);
      if (a_.bias == BiasRule::Exact) {  // a contact's β from the moved anchors, its J̌ held
        for (const ContactDef& contact : cs.contacts) {
          Row& r = cs.rows[static_cast<size_t>(contact.row)];
          Row fresh = r;
          formulateContact(contact, c.subPoses[static_cast<size_t>(contact.a)], c.subPoses[static_cast<size_t>(contact.b)],
                           dt, c.settings->slop, fresh, false);
          r.bias = fresh.bias - r.split;
        }
      }
    } else {
      cs.reformulate(c.subPoses, c.mass, dt, ConstraintSet::Reformulation::Everything, 1.0);
    }
    // Velocity-level rows (friction, motors) keep the β just formulated: a target, not a C.
    if (a_.bias == BiasRule::Update) {
      for (size_t k = 0; k < cs.rows.size(); ++k)
        if (!cs.rows[k].velocityLevel) cs.rows[k].bias = updated_[k];
    } else if (a_.bias == BiasRule::UpdateOneJacobian) {
      for (size_t k = 0; k < cs.rows.size(); ++k) {
        Row& r = cs.rows[k];
        if (!r.velocityLevel) r.bias = first_[k] - rowVelocity(r, sumV_.data(), sumW_.data());  // β¹ - J̌ʲ⁺¹ Σ v̌ᵏ
      }
    }
  }

  Approximations a_;
  std::vector<double> updated_, first_;  // βʲ⁺¹ by the update rule; β¹
  std::vector<Vec3> sumV_, sumW_;        // Σ_{k<=j} v̌ᵏ, unscaled
};

}  // namespace

std::unique_ptr<Stepper> makeHavokConceptualStepper(const Approximations& a) {
  return std::make_unique<HavokConceptualStepper>(a);
}

}  // namespace substep

// The soft step: Box2D v3's sub-stepping solver (Catto, "Solver2D"; Box2D v3's solver.c and
// contact_solver.c) in 3D, on the project's rows. Not one of the report's algorithms: an
// extension to chart A3-A5 against (docs/algorithms.md, "The soft step", relates it symbol by
// symbol). Per sub-step of h = dt/n:
//   1. v̌ += h g                                   (ext, as proc3:6)
//   2. warm start: v̌ += M̌⁻¹J̌ᵀλ                    (the impulses of the last sub-step)
//   3. solve, soft: per row  Δλ = -m_eff (s_m J̌v̌ + b) - s_i λ,  λ projected
//   4. integrate the coordinates with these velocities (exact rotation product, as proc3:19)
//   5. relax: the same rows rigid and without position feedback (s_m = 1, s_i = 0, b = 0)
// and after the sub-steps restitution (applyRestitution). Soft rows (Box2D's b2MakeSoft, for a
// stiffness f [Hz] and damping ratio ζ): ω = 2πf, a = 2ζ + hω,
//   biasRate = ω / a,   s_m (massScale) = hωa / (1 + hωa),   s_i (impulseScale) = 1 / (1 + hωa)
// so s_m + s_i = 1; a contact's b = max(s_m biasRate C, -pushOut) for C < 0. A point apart
// (C > 0) is speculative: b = C/h, rigid, in both passes. C of a contact follows the bodies'
// motion within the step with J̌ held, C = C⁰ + J̌ Σ h v̌ᵏ, which is the report's bias update rule
// (proc4:16, IV.3.1.3); joints are re-formulated from the coordinates every sub-step.
// Contacts against static bodies are twice as stiff; friction and motors are rigid.
#include "physics/steppers/stepper.h"

#include <algorithm>
#include <cmath>

namespace substep {

namespace {

struct Softness {
  double biasRate = 0, massScale = 1, impulseScale = 0;
};

Softness makeSoft(double hertz, double zeta, double h) {
  if (hertz == 0) return {0, 1, 0};
  const double omega = 2 * M_PI * hertz;
  const double a1 = 2 * zeta + h * omega, a2 = h * omega * a1, a3 = 1 / (1 + a2);
  return {omega / a1, a2 * a3, a3};
}

class SoftStepper final : public Stepper {
 public:
  void stepVelocities(StepContext& c) override {
    ConstraintSet& cs = *c.constraints;
    const SolverSettings& st = *c.settings;
    const int n = c.n(), m = st.iterations;
    const double h = c.h() / n;
    const size_t nb = c.bodies();
    // Box2D lowers the frequencies for large sub-steps: a contact at most a quarter of the
    // sub-step rate, a joint an eighth. Here joints are capped at a quarter too: at an eighth
    // (30 Hz at n = 4, h = 1/60) a hanging 30-link chain's joints stretch 22 mm on average against
    // A5's 8 mm; at a quarter 5.7 mm (docs/algorithms.md).
    const double contactHz = std::min(st.contactHertz, 0.25 / h);
    const Softness contact = makeSoft(contactHz, st.contactDamping, h);
    const Softness staticContact = makeSoft(2 * contactHz, st.contactDamping, h);
    const Softness joint = makeSoft(std::min(st.jointHertz, 0.25 / h), st.jointDamping, h);
    c.stats = StepStats{};
    c.rowsHeld = cs.joints.empty();  // contact J̌ held over the step; joints re-formulated
    c.stats.rows = static_cast<int>(cs.rows.size());

    // What each row is, and for contacts C⁰ and the softness.
    soft_[kJointSoft] = joint;
    soft_[kContactSoft] = contact;
    soft_[kStaticSoft] = staticContact;
    kind_.assign(cs.rows.size(), Kind::Joint);
    softOf_.assign(cs.rows.size(), kJointSoft);
    c0_.assign(cs.rows.size(), 0.0);
    for (size_t k = 0; k < cs.rows.size(); ++k) {
      const Row& r = cs.rows[k];
      if (r.velocityTarget) kind_[k] = Kind::Target;
      else if (r.velocityLevel) kind_[k] = Kind::Friction;
      else if (r.lo == 0 && std::isinf(r.hi)) kind_[k] = Kind::Limit;  // joint limits: C from β
    }
    for (const ContactDef& ct : cs.contacts) {
      const size_t k = static_cast<size_t>(ct.row);
      kind_[k] = Kind::Contact;
      c0_[k] = -cs.rows[k].bias * h;  // β = -C/h as s2 formulated it
      const bool onStatic = c.model->bodies[static_cast<size_t>(ct.a)].isStatic ||
                            c.model->bodies[static_cast<size_t>(ct.b)].isStatic;
      softOf_[k] = onStatic ? kStaticSoft : kContactSoft;
    }
    dpV_.assign(nb, Vec3::Zero());
    dpW_.assign(nb, Vec3::Zero());
    c.subPoses = c.poses;
    const Pass solve{true, h, st.pushOut}, relax{false, h, st.pushOut};

    for (int j = 0; j < n; ++j) {
      addExternal(c, h);
      startSubStepImpulses(c, j);
      for (int i = 0; i < m && !cs.rows.empty(); ++i) c.stats.residual = softSweep(c, solve);
      // Coordinates to the sub-step's end with the solved (biased) velocities.
      for (size_t i = 0; i < nb; ++i) {
        if (c.model->bodies[i].isStatic) continue;
        dpV_[i] += h * c.v[i];
        dpW_[i] += h * c.w[i];
        c.subPoses[i].p += h * c.v[i];
        c.subPoses[i].q = (c.subPoses[i].q * Rq(h * c.w[i])).normalized();
      }
      recordSubStep(c, j);
      if (!cs.joints.empty()) cs.reformulate(c.subPoses, c.mass, h, ConstraintSet::Reformulation::JointRows, 1.0);
      for (int i = 0; i < m && !cs.rows.empty(); ++i) softSweep(c, relax);
      endSubStepImpulses(c);
    }
    c.stats.iterations = 2 * n * m;
    applyRestitution(c, c.v.data(), c.w.data(), 1.0);
  }

  // s4: the sub-steps moved the coordinates already; the velocity is the relaxed one.
  void stepCoordinates(StepContext& c) override {
    for (size_t i = 0; i < c.bodies(); ++i) {
      if (c.model->bodies[i].isStatic) continue;
      BodyState& b = c.state->bodies[i];
      b.x = c.subPoses[i].p;
      b.q = c.subPoses[i].q;
      b.v = endVelocity(c, i, c.v[i]);
      b.w = endAngularVelocity(c, i, c.w[i]);
    }
  }

 private:
  enum class Kind : unsigned char { Contact, Friction, Target, Joint, Limit };

  struct Pass {
    bool useBias;   // the solve (soft, with position feedback) or the relax (rigid, none)
    double h;       // the sub-step [s]
    double pushOut; // [m/s]
  };

  // Row k's update Δλ = -(a J̌v̌ + b) - s_i λ in this pass: a = s_m m_eff, b = m_eff bias. A
  // contact's C is C⁰ + J̌·(Σ h v̌ᵏ) at the coordinates reached, J̌ held; joints were
  // re-formulated from them, so their C is -β h.
  struct Update {
    double a, b, si;
  };
  Update update(const Row& r, size_t k, const Pass& p) const {
    double bias = 0, massScale = 1, impulseScale = 0;  // rigid, no feedback: relax
    switch (kind_[k]) {
      case Kind::Friction: break;
      case Kind::Target: bias = -r.bias; break;  // J̌v̌ = target speed
      case Kind::Contact:
      case Kind::Limit:
      case Kind::Joint: {
        const double C = kind_[k] == Kind::Contact ? c0_[k] + rowVelocity(r, dpV_.data(), dpW_.data()) : -r.bias * p.h;
        if (kind_[k] != Kind::Joint && C > 0) {
          bias = C / p.h;  // speculative: close the gap in this sub-step and no further
        } else if (p.useBias) {
          const Softness& s = soft_[softOf_[k]];
          bias = s.massScale * s.biasRate * C;
          if (kind_[k] == Kind::Contact) bias = std::max(bias, -p.pushOut);
          massScale = s.massScale;
          impulseScale = s.impulseScale;
        }
        break;
      }
    }
    return {massScale * r.effMass, bias * r.effMass, impulseScale};
  }

  // One sweep, row by row (the soft step solves no blocks; a manifold's friction rows as one
  // unit, their two bodies' velocities read once), each row's update computed as it is reached:
  // one pass over the rows per sweep.
  double softSweep(StepContext& c, const Pass& p) {
    ConstraintSet& cs = *c.constraints;
    Row* rows = cs.rows.data();
    Vec3* v = c.v.data();
    Vec3* w = c.w.data();
    double change = 0;
    for (const SolveUnit& u : cs.units) {
      if (u.kind == SolveUnit::Friction) {  // rigid in both passes: Δλ = -m_eff J̌v̌
        const int ia = rows[u.first].a, ib = rows[u.first].b;
        solveFrictionUnit(cs.couplings[static_cast<size_t>(u.block)], &rows[u.first], rows, v[ia], w[ia], v[ib], w[ib], 0, 1,
                          change);
        continue;
      }
      for (int q = 0; q < u.size; ++q) {
        const size_t k = static_cast<size_t>(u.first + q);
        Row& r = rows[k];
        const Update d = update(r, k, p);
        change = std::max(change, solveRow(r, rows, v, w, [&](double jv) { return -(d.a * jv + d.b) - d.si * r.lambda; }));
      }
    }
    return change;
  }

  static constexpr unsigned char kContactSoft = 0, kStaticSoft = 1, kJointSoft = 2;
  Softness soft_[3];
  std::vector<Kind> kind_;
  std::vector<unsigned char> softOf_;  // which of soft_ a row takes
  std::vector<double> c0_;         // contacts: C at the step's start [m]
  std::vector<Vec3> dpV_, dpW_;    // Σ h v̌ᵏ of the sub-steps so far (angular in the body frame)
};

}  // namespace

std::unique_ptr<Stepper> makeSoftStepper() { return std::make_unique<SoftStepper>(); }

}  // namespace substep

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
//
// Order: the joints' rows first, then the manifolds in the step's order; or, with
// SolverSettings::colours, colour by colour as Box2D v3's solver.c does: no two manifolds of a
// colour share a moving body, and each colour's (in the step's order) are solved on the step's
// threads. Within a colour no manifold reads what another writes, so the trajectory is the same
// to the last bit for any number of threads. The manifolds are solved eight at a time in SIMD lanes
// (soft_lanes.h, SolverSettings::lanes) in runs that share no moving body: the colours, or
// uncoloured runs of the step's order (LaneRuns), which give its numbers to the last bit;
// a run's groups go to the threads, or where runs are short each group to a thread of its own
// once those before it on its bodies are done (OrderedSchedule). Without the lanes (or in a split
// contact order) one manifold at a time, uncoloured the islands to the threads island by island:
// the same trajectory again.
#include "physics/steppers/soft_lanes.h"
#include "physics/constraints/lane_runs.h"
#include "physics/step_arrays.h"
#include "physics/steppers/soft_lanes_fill.h"
#include "physics/steppers/stepper.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>

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

static_assert(sizeof(Vec3) == 3 * sizeof(double), "the lanes read velocities as three doubles a body");

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
    c.stats.rows = cs.rowCount();

    // What each row is, and for contacts C⁰ and the softness.
    soft_[kJointSoft] = joint;
    soft_[kContactSoft] = contact;
    soft_[kStaticSoft] = staticContact;
    // The manifolds in lanes take their C⁰ and softness from the rows as the lanes are built:
    // then only the joints' rows (those before the contacts') are classified here.
    lanes_ = st.lanes && st.contactOrder == ContactOrder::Manifold && !cs.frictions.empty();
    const size_t classified = lanes_ ? static_cast<size_t>(cs.contactFirstRow) : cs.rows.size();
    kind_.resize(cs.rows.size());
    softOf_.resize(cs.rows.size());
    c0_.resize(cs.rows.size());
    c.workers().forRange(classified, 1024, [&](size_t first, size_t last, int) {
      for (size_t k = first; k < last; ++k) {
        const Row& r = cs.rows[k];
        kind_[k] = Kind::Joint;
        softOf_[k] = kJointSoft;
        c0_[k] = 0;
        if (r.velocityTarget) kind_[k] = Kind::Target;
        else if (r.velocityLevel) kind_[k] = Kind::Friction;
        else if (r.lo == 0 && std::isinf(r.hi)) kind_[k] = Kind::Limit;  // joint limits: C from β
      }
    });
    if (!lanes_)
      c.workers().forRange(cs.contacts.size(), 1024, [&](size_t first, size_t last, int) {
        for (size_t q = first; q < last; ++q) {
          const ContactDef& ct = cs.contacts[q];
          const size_t k = static_cast<size_t>(ct.row);
          kind_[k] = Kind::Contact;
          c0_[k] = contactC0(cs.rows[k], h);
          softOf_[k] = onStatic(c, ct.a, ct.b) ? kStaticSoft : kContactSoft;
        }
      });
    // Sized here; each body started by its block in the first sub-step's first job, not on the
    // calling thread (docs/benchmarks.md, "s2's serial parts").
    dpV_.resize(nb);
    dpW_.resize(nb);
    sizeSubSteps(c);
    prepareSweeps(c);
    const Pass solve{true, h, st.pushOut}, relax{false, h, st.pushOut};

    // Warm and held (no joints), the warm start's per-body part goes with v += h g, per body on
    // the threads; else row by row (startImpulses).
    const bool perBody = st.warmStart && c.rowsHeld;
    for (int j = 0; j < n; ++j) {
      eachBodyBlock(c, [&](size_t first, size_t last) {
        if (j == 0) {
          beginSubSteps(c, first, last);
          std::fill(dpV_.begin() + static_cast<long>(first), dpV_.begin() + static_cast<long>(last), Vec3::Zero());
          std::fill(dpW_.begin() + static_cast<long>(first), dpW_.begin() + static_cast<long>(last), Vec3::Zero());
        }
        addExternal(c, h, first, last);
        if (perBody) startSubStepImpulses(c, j, bodyPart(first, last));
      });
      startImpulses(c, j, perBody);
      // The step reports the residual of its last solve sweep; the others do not measure it.
      for (int i = 0; i < m && c.stats.rows > 0; ++i) {
        if (j + 1 == n && i + 1 == m) c.stats.residual = softSweep<true>(c, solve);
        else softSweep<false>(c, solve);
      }
      // Coordinates to the sub-step's end with the solved (biased) velocities, which are the
      // sub-step's record.
      eachBodyBlock(c, [&](size_t first, size_t last) {
        for (size_t i = first; i < last; ++i) {
          recordSubStep(c, j, i);
          if (c.model->bodies[i].isStatic) continue;
          dpV_[i] += h * c.v[i];
          dpW_[i] += h * c.w[i];
          c.subPoses[i].p += h * c.v[i];
          c.subPoses[i].q = (c.subPoses[i].q * Rq(h * c.w[i])).normalized();
        }
      });
      if (!cs.joints.empty()) cs.reformulate(c.subPoses, c.mass, h, ConstraintSet::Reformulation::JointRows, 1.0);
      for (int i = 0; i < m && c.stats.rows > 0; ++i) softSweep<false>(c, relax);
      // Back to the rows, where the next sub-step's warm start (with joints, J̌ re-formulated)
      // and after the step restitution, the forces and the next step read them.
      if (lanes_ && cs.contactRowsDeferred() && j + 1 == n) lanesToImpulses(c);
      else if (lanes_ && (j + 1 == n || !c.rowsHeld || !st.warmStart)) lanesToRows(c);
      if (perBody) eachBodyBlock(c, [&](size_t first, size_t last) { endSubStepImpulses(c, bodyPart(first, last)); });
    }
    c.stats.iterations = 2 * n * m;
    applyRestitution(c, c.v.data(), c.w.data(), 1.0);
  }

  // In lanes, warm and held (no joints), the contacts' rows are formulated as the lanes are filled.
  bool formulatesContactRows(const SolverSettings& st) const override {
    return st.lanes && st.contactOrder == ContactOrder::Manifold && st.warmStart;
  }

  // s4: the sub-steps moved the coordinates already; the velocity is the relaxed one.
  void stepCoordinates(StepContext& c) override {
    eachBodyBlock(c, [&](size_t first, size_t last) {
      for (size_t i = first; i < last; ++i) {
        if (c.model->bodies[i].isStatic) continue;
        BodyState& b = c.state->bodies[i];
        b.x = c.subPoses[i].p;
        b.q = c.subPoses[i].q;
        b.v = endVelocity(c, i, c.v[i]);
        b.w = endAngularVelocity(c, i, c.w[i]);
      }
    });
  }

 private:
  enum class Kind : unsigned char { Contact, Friction, Target, Joint, Limit };

  struct Pass {
    bool useBias;   // the solve (soft, with position feedback) or the relax (rigid, none)
    double h;       // the sub-step [s]
    double pushOut; // [m/s]
  };

  // Row k's update Δλ = -(a J̌v̌ + b) - s_i λ in this pass: a = s_m m_eff, b = m_eff bias.
  struct Update {
    double a, b, si;
  };
  // From a row's position error C: soft with feedback in the solve, rigid without it in the
  // relax; an inequality apart (C > 0) is speculative in both, closing the gap in this sub-step
  // and no further; a contact pushes out at most at pushOut.
  static Update positional(double C, bool inequality, bool contact, const Softness& s, double effMass, const Pass& p) {
    double bias = 0, massScale = 1, impulseScale = 0;
    if (inequality && C > 0) {
      bias = C / p.h;
    } else if (p.useBias) {
      bias = s.massScale * s.biasRate * C;
      if (contact) bias = std::max(bias, -p.pushOut);
      massScale = s.massScale;
      impulseScale = s.impulseScale;
    }
    return {massScale * effMass, bias * effMass, impulseScale};
  }
  // A joint's row: re-formulated from the sub-step's coordinates, so its C is -β h.
  Update jointUpdate(const Row& r, size_t k, const Pass& p) const {
    switch (kind_[k]) {
      case Kind::Target: return {r.effMass, -r.bias * r.effMass, 0};  // J̌v̌ = target speed
      case Kind::Joint:
      case Kind::Limit: return positional(-r.bias * p.h, kind_[k] == Kind::Limit, false, soft_[softOf_[k]], r.effMass, p);
      default: return {r.effMass, 0, 0};  // rigid, no bias (friction)
    }
  }
  // A manifold's normal row: C = C⁰ + J̌·(Σ h v̌ᵏ) at the coordinates reached, J̌ held; the
  // bodies' Σ h v̌ᵏ read once a manifold.
  Update contactUpdate(const Row& r, size_t k, const Softness& s, const Vec3& dpA, const Vec3& dwA, const Vec3& dpB,
                       const Vec3& dwB, const Pass& p) const {
    return positional(c0_[k] + rowVelocity(r, dpA, dwA, dpB, dwB), true, true, s, r.effMass, p);
  }

  // What a sweep needs of the step's colours (ConstraintSet::colourOrder).
  void prepareSweeps(StepContext& c) {
    const ConstraintSet& cs = *c.constraints;
    // The joints' solve units: those before the first contact unit.
    jointUnits_ = cs.joints.empty() ? 0 : cs.joints.back().firstUnit + cs.joints.back().units;
    // A manifold's rows in the order the settings give: its normals, then its friction (Box2D's);
    // or, split, all friction then all normals when warm, all normals then all friction cold.
    const ContactOrder order = c.settings->contactOrder;
    phaseCount_ = order == ContactOrder::Manifold ? 1 : 2;
    phases_[0] = order == ContactOrder::Manifold ? Phase::Both : c.settings->warmStart ? Phase::Friction : Phase::Normals;
    phases_[1] = c.settings->warmStart ? Phase::Normals : Phase::Friction;
    change_.reset(c.workers().threads());
    if (lanes_) buildLanes(c);
  }

  // The colours in the order they are solved: from the highest down, the overflow last.
  template <class F>
  static void eachColour(F f) {
    for (int ci = 0; ci <= ConstraintSet::kColours; ++ci)
      f(ci == ConstraintSet::kColours ? ci : ConstraintSet::kColours - 1 - ci);
  }

  // The manifolds eight to a group (soft_lanes.h), in runs whose manifolds share no body that
  // moves, solved run after run: the colours (from the highest down, the overflow last, one to a
  // group since its manifolds share bodies), or uncoloured the sweep's runs (LaneRuns).
  void buildLanes(StepContext& c) {
    const ConstraintSet& cs = *c.constraints;
    const Row* rows = cs.rows.data();
    segments_.clear();
    size_t groups = 0;
    const auto run = [&](size_t first, size_t count, bool serial) {
      if (count == 0) return;
      const size_t n = serial ? count : (count + lanes::kLanes - 1) / lanes::kLanes;
      segments_.push_back({groups, groups + n, first, count, serial});
      groups += n;
    };
    if (cs.colourStart.empty()) {
      runs_.order(cs.frictions, c.mass);
      laneOrder_ = runs_.manifolds().data();
      const std::vector<int>& start = runs_.starts();
      for (size_t r = 0; r + 1 < start.size(); ++r)
        run(static_cast<size_t>(start[r]), static_cast<size_t>(start[r + 1] - start[r]), false);
    } else {
      const std::vector<int>& start = cs.colourStart;
      laneOrder_ = cs.colourOrder.data();
      eachColour([&](int col) {
        const size_t first = static_cast<size_t>(start[static_cast<size_t>(col)]);
        run(first, static_cast<size_t>(start[static_cast<size_t>(col) + 1]) - first, col == ConstraintSet::kColours);
      });
    }
    const int* order = laneOrder_;
    c.stats.laneRuns = static_cast<int>(segments_.size());
    c.stats.laneGroups = static_cast<int>(groups);
    resizeRewritten(groups_, groups, c.workers());
    const double h = c.h() / c.n();
    const bool deferred = cs.contactRowsDeferred();
    // Deferred in the world contact frame (the soft step's default), the kernel formulates the
    // group's manifolds side by side, from their definitions gathered lane by lane; in the bodies'
    // frame each lane's manifold is formulated on its own (formulateManifold) and its rows copied in.
    const bool inLanes = deferred && c.settings->contactFrame == ContactFrame::World;
    const lanes::Formulation formulation = lanes::formulation(cs, h);
    const lanes::Kernel& kernel = lanes::kernel();
    const bool ahead = LaneRuns::outgrowsL2(cs.manifoldBytes());
    // inLanes: what the kernel formulates from, one a thread (zeroed once, so a lane not in use,
    // which the kernel makes zero rows of, holds numbers an earlier group left, not garbage).
    if (inLanes) definitions_.resize(static_cast<size_t>(c.workers().threads()));
    const auto fill = [&](const Segment& seg, size_t gi, int thread) {
      lanes::Group& g = groups_[gi];
      Row formulated[lanes::kMaxNormals + 3];  // deferred: a lane's manifold's rows, as build() would store them
      FrictionCoupling coupling;
      const size_t per = seg.serial ? 1 : lanes::kLanes;
      const size_t first = (gi - seg.first) * per;
      g.count = static_cast<int>(std::min(per, seg.count - first));
      g.normals = 0;
      for (int l = 0; l < lanes::kLanes; ++l) {
        const size_t at = seg.order + first + static_cast<size_t>(l), end = seg.order + seg.count;
        if (ahead && at + 2 * LaneRuns::kAhead < end) __builtin_prefetch(&cs.frictions[static_cast<size_t>(order[at + 2 * LaneRuns::kAhead])]);
        if (ahead && at + LaneRuns::kAhead < end) cs.prefetchManifold(static_cast<size_t>(order[at + LaneRuns::kAhead]));
        // A lane not in use reads lane 0's bodies and, with zero rows and masses, writes nothing.
        const bool used = l < g.count;
        const size_t k = static_cast<size_t>(order[used ? at : seg.order + first]);
        const FrictionDef& f = cs.frictions[k];
        g.manifold[l] = static_cast<int>(k);
        g.a[l] = f.a;
        g.b[l] = f.b;
        const BodyMass& A = c.mass[static_cast<size_t>(f.a)];
        const BodyMass& B = c.mass[static_cast<size_t>(f.b)];
        const Softness& s = soft_[onStatic(c, f.a, f.b) ? kStaticSoft : kContactSoft];
        g.massScale.x[l] = s.massScale;
        g.biasRate.x[l] = s.biasRate;
        g.impulseScale.x[l] = s.impulseScale;
        lanes::putMasses(g, l, A, B, used);
        const int normals = used ? f.normalCount : 0;
        g.normals = std::max(g.normals, normals);
        if (inLanes) {
          if (used) lanes::gatherManifold(cs, k, l, definitions_[static_cast<size_t>(thread)]);
          continue;
        }
        if (deferred && used) cs.formulateManifold(k, formulated, coupling);
        const Row* normalRows = deferred ? formulated : &rows[f.firstNormal];
        const Row* frictionRows = deferred ? formulated + f.normalCount : &rows[f.row];
        // (The masses above: checked where asserts run.)
        assert(!used || (frictionRows[0].mA == A.invMass && frictionRows[0].mB == B.invMass &&
                         frictionRows[0].mAngA == A.invI.cwiseProduct(frictionRows[0].angA)));
        const FrictionCoupling& cp =
            deferred ? coupling : cs.couplings[static_cast<size_t>(cs.units[static_cast<size_t>(f.frictionUnit)].block)];
        g.g10.x[l] = used ? cp.g10 : 0;
        g.g20.x[l] = used ? cp.g20 : 0;
        g.g21.x[l] = used ? cp.g21 : 0;
        for (int q = 0; q < lanes::kMaxNormals; ++q) {
          // A point held (λ in [0, 0]: apart without speculative points) is a zero row: the lanes
          // bound every normal to [0, ∞).
          const Row* r = q < normals && normalRows[q].hi != 0 ? &normalRows[q] : nullptr;
          assert(!r || (r->lo == 0 && std::isinf(r->hi)));
          laneRow(g.normal[q], l, r);
          g.normal[q].c0.x[l] = r ? contactC0(*r, h) : 0;
        }
        for (int i = 0; i < 3; ++i) {
          const Row* r = used ? &frictionRows[i] : nullptr;
          assert(!r || (r->bias == 0 && r->lo == -r->hi && r->normalRow == f.firstNormal && r->normalCount == f.normalCount));
          laneRow(g.friction[i], l, r);
          g.friction[i].mu.x[l] = r ? r->hi : 0;
        }
      }
      if (inLanes) kernel.formulate(definitions_[static_cast<size_t>(thread)], g, formulation);
    };
    // Every run's groups in one job: a run is a few groups (three on the 100-level pyramid),
    // less than one block, so a job a run would leave them all to the calling thread.
    c.workers().forRange(groups, 16, [&](size_t b, size_t e, int thread) {
      auto seg = std::upper_bound(segments_.begin(), segments_.end(), b,
                                  [](size_t gi, const Segment& s) { return gi < s.last; });
      for (size_t gi = b; gi < e; ++gi) {
        while (seg->last <= gi) ++seg;
        fill(*seg, gi, thread);
      }
    });
    // Runs shorter on average than two blocks a thread (a pyramid's: two or three groups, most
    // left to one thread and each ended by a wait for all) go by OrderedSchedule instead: each
    // group on its thread once those before it on its moving bodies are done, whatever their
    // run. Long runs (a pile's) are shared out run by run, a block at a time.
    const int threads = c.workers().threads();
    scheduled_ = threads > 1 && cs.colourStart.empty() &&
                 groups < segments_.size() * 2 * static_cast<size_t>(threads) * kRunGrain;
    c.stats.laneScheduled = scheduled_;
    if (scheduled_) {
      auto seg = segments_.begin();  // the run of the group asked for (asked in order)
      schedule_.build(
          groups, c.bodies(), threads, [&](size_t gi, auto follow) { lanes::eachMovingBody(groups_[gi], follow); },
          [&](size_t gi) {
            while (seg->last <= gi) ++seg;
            return std::pair<size_t, size_t>(seg->first, seg->last);
          });
    }
  }
  // Row r into lane l (null: a zero row), with its λ and pushed as the step starts.
  static void laneRow(lanes::RowLanes& to, int l, const Row* r) {
    for (int i = 0; i < 3; ++i) {
      to.lin[i].x[l] = r ? r->lin[i] : 0;
      to.angA[i].x[l] = r ? r->angA[i] : 0;
      to.angB[i].x[l] = r ? r->angB[i] : 0;
    }
    to.effMass.x[l] = r ? r->effMass : 0;
    to.lambda.x[l] = r ? r->lambda : 0;
    to.pushed.x[l] = r && r->pushed ? -1 : 0;
  }

  // f(group, lane, its manifold's definition) for every lane in use, the groups on the threads.
  template <class F>
  void eachLane(StepContext& c, F f) {
    const std::vector<FrictionDef>& frictions = c.constraints->frictions;
    c.workers().forRange(groups_.size(), 64, [&](size_t b, size_t e, int) {
      for (size_t gi = b; gi < e; ++gi) {
        lanes::Group& g = groups_[gi];
        for (int l = 0; l < g.count; ++l) f(g, l, frictions[static_cast<size_t>(g.manifold[l])]);
      }
    });
  }
  // f(group's row lanes, lane, row) for every row of every manifold in the lanes.
  template <class F>
  void eachLaneRow(StepContext& c, F f) {
    Row* rows = c.constraints->rows.data();
    eachLane(c, [&](lanes::Group& g, int l, const FrictionDef& fd) {
      for (int q = 0; q < fd.normalCount; ++q) f(g.normal[q], l, rows[fd.firstNormal + q]);
      for (int i = 0; i < 3; ++i) f(g.friction[i], l, rows[fd.row + i]);
    });
  }
  void lanesFromRows(StepContext& c) {
    eachLaneRow(c, [](lanes::RowLanes& to, int l, const Row& r) {
      to.lambda.x[l] = r.lambda;
      to.pushed.x[l] = r.pushed ? -1 : 0;
    });
  }
  void lanesToRows(StepContext& c) {
    eachLaneRow(c, [](lanes::RowLanes& from, int l, Row& r) {
      r.lambda = from.lambda.x[l];
      r.pushed = from.pushed.x[l] != 0;
    });
  }

  // Deferred contact rows (no row to write back to): each manifold's impulses for storeImpulses,
  // as it would take them from the rows.
  void lanesToImpulses(StepContext& c) {
    ConstraintSet& cs = *c.constraints;
    resizeRewritten(cs.impulses, cs.frictions.size(), c.workers());
    eachLane(c, [&](const lanes::Group& g, int l, const FrictionDef& fd) {
      ConstraintSet::ManifoldImpulses& to = cs.impulses[static_cast<size_t>(g.manifold[l])];
      for (int q = 0; q < fd.normalCount; ++q) to.normal[q] = g.normal[q].lambda.x[l];
      const lanes::FrictionLanes* f = g.friction;
      to.tangentInB = frictionImpulseInB(fd.qB, f[0].lambda.x[l], lanes::laneVector(f[0].lin, l), f[1].lambda.x[l],
                                         lanes::laneVector(f[1].lin, l));
      to.twist = f[2].lambda.x[l];
    });
  }

  // The manifolds' part of a sweep in the lanes.
  void sweepLanes(StepContext& c, const Pass& p, bool measure) {
    const lanes::Kernel& k = lanes::kernel();
    const lanes::Pass lp{p.useBias, p.h, p.pushOut};
    const double* dpV = dpV_.data()->data();
    const double* dpW = dpW_.data()->data();
    eachSegment(c, [&](size_t first, size_t last, int t) {
      onBlock(t, [&](double& change) {
        change = std::max(change, k.solve(groups_.data(), first, last, vel(c.v), vel(c.w), dpV, dpW, lp, measure));
      });
    });
  }

  // f(first, last, thread) over the lanes' groups: by the schedule, or run by run, each run's on
  // the threads, the colours' overflow in order on this one. On one thread the runs, which lie one
  // after another, are one range: the same groups in the same order.
  template <class F>
  void eachSegment(StepContext& c, F f) {
    if (scheduled_) {
      schedule_.run(c.workers(), f);
      return;
    }
    if (c.workers().threads() == 1) {
      if (!segments_.empty()) f(segments_.front().first, segments_.back().last, 0);
      return;
    }
    for (const Segment& seg : segments_) {
      if (seg.serial) f(seg.first, seg.last, 0);
      else
        c.workers().forRange(seg.last - seg.first, kRunGrain, [&](size_t b, size_t e, int t) { f(seg.first + b, seg.first + e, t); });
    }
  }
  static double* vel(std::vector<Vec3>& v) { return v.data()->data(); }
  // A contact's C at the step's start from β = -C/h as s2 formulated it.
  static double contactC0(const Row& r, double h) { return -r.bias * h; }
  // Contacts against static bodies are twice as stiff.
  static bool onStatic(const StepContext& c, int a, int b) {
    return c.model->bodies[static_cast<size_t>(a)].isStatic || c.model->bodies[static_cast<size_t>(b)].isStatic;
  }

  static ConstraintPart bodyPart(size_t first, size_t last) {
    return ConstraintPart{{}, {}, IndexRange{nullptr, static_cast<int>(first), static_cast<int>(last - first)}, {}};
  }

  // f(manifold index, change) for every manifold, colour by colour, each colour's on the threads;
  // change: where f keeps the largest velocity change it made, the thread's share of change_.
  template <class F>
  void eachManifold(StepContext& c, F f) {
    const std::vector<int>& order = c.constraints->colourOrder;
    const std::vector<int>& start = c.constraints->colourStart;
    if (start.empty()) {  // not coloured: in the step's order
      const ConstraintSet& cs = *c.constraints;
      const int islands = cs.islandCount();
      if (islands <= 1 || c.workers().threads() == 1) {
        for (size_t k = 0; k < cs.frictions.size(); ++k) f(k, change_.of(0));
        return;
      }
      // Islands share no body that moves: each island's manifolds in the step's order, the
      // islands spread over the threads, give the numbers of the serial order, and one running
      // maximum per thread the same largest change. About kIslandGrain manifolds a block: blocks
      // of neighbouring islands on different threads share the cache lines of their boundary
      // bodies' velocities, which cost more than the sweep saved with blocks of 32.
      const size_t grain = std::max<size_t>(1, static_cast<size_t>(islands) * kIslandGrain / std::max<size_t>(1, cs.frictions.size()));
      c.workers().forRange(static_cast<size_t>(islands), grain, [&](size_t b, size_t e, int t) {
        onBlock(t, [&](double& change) {
          for (size_t i = b; i < e; ++i) {
            const IndexRange list = cs.islandManifolds(static_cast<int>(i));
            for (int q = 0; q < list.count; ++q) f(static_cast<size_t>(list[q]), change);
          }
        });
      });
      return;
    }
    // From the highest colour down, the overflow last: the manifolds with a static body first,
    // then those between moving bodies from the last colour assigned to the first.
    for (int ci = 0; ci <= ConstraintSet::kColours; ++ci) {
      const int col = ci == ConstraintSet::kColours ? ci : ConstraintSet::kColours - 1 - ci;
      const int first = start[static_cast<size_t>(col)], last = start[static_cast<size_t>(col) + 1];
      if (first == last) continue;
      const auto inOrder = [&](size_t b, size_t e, int t) {
        onBlock(t, [&](double& change) {
          for (size_t q = b; q < e; ++q) f(static_cast<size_t>(order[static_cast<size_t>(first) + q]), change);
        });
      };
      const size_t count = static_cast<size_t>(last - first);
      if (col == ConstraintSet::kColours) inOrder(0, count, 0);  // the overflow: in order, on this thread
      else c.workers().forRange(count, kManifoldGrain, inOrder);
    }
  }

  // body(change) for a block of manifolds on thread t, then the block's largest change into the
  // thread's slot (kept in the block until then: threads writing neighbouring slots would share a
  // cache line).
  template <class B>
  void onBlock(int t, B body) {
    double change = 0;
    body(change);
    double& mine = change_.of(t);
    mine = std::max(mine, change);
  }

  // Warm start: sub-step 0 applies last step's λ on this step's J̌ (joints' rows, then each
  // manifold's, colour by colour); later sub-steps as startSubStepImpulses does. perBody: the
  // per-body part (startSubStepImpulses of every body, warm with J̌ held) is done already.
  void startImpulses(StepContext& c, int j, bool perBody) {
    ConstraintSet& cs = *c.constraints;
    const bool warm = c.settings->warmStart;
    if (j > 0 || !warm || !c.rowsHeld) {
      if (!perBody) startSubStepImpulses(c, j);
      // The lanes hold the contacts' λ from here to the sub-step's end (buildLanes took the
      // step's first): cold, the rows' were zeroed.
      if (lanes_ && j > 0 && !warm) lanesFromRows(c);
      return;
    }
    // j = 0, warm, held: last step's λ on this step's J̌, row by row (the joints' none, as held).
    applyRowImpulses(cs, IndexRange{nullptr, 0, cs.contactFirstRow}, c.v, c.w);
    if (lanes_) {
      const lanes::Kernel& k = lanes::kernel();
      eachSegment(c, [&](size_t first, size_t last, int) { k.warmStart(groups_.data(), first, last, vel(c.v), vel(c.w)); });
      return;
    }
    Row* rows = cs.rows.data();
    eachManifold(c, [&](size_t k, double&) {
      const FrictionDef& f = cs.frictions[k];
      Vec3 va = c.v[static_cast<size_t>(f.a)], wa = c.w[static_cast<size_t>(f.a)];
      Vec3 vb = c.v[static_cast<size_t>(f.b)], wb = c.w[static_cast<size_t>(f.b)];
      for (int r = f.firstNormal; r < f.row + 3; ++r)
        if (rows[r].lambda != 0) applyImpulse(rows[r], rows[r].lambda, va, wa, vb, wb);
      storeMoving(rows[f.row], va, wa, vb, wb, c.v.data(), c.w.data());  // the manifold's bodies and M̌⁻¹
    });
  }

  // One sweep: the joints' units row by row (a manifold's friction rows as one unit, their two
  // bodies' velocities read once), then the manifolds colour by colour, each row's update
  // computed as it is reached. Measure: return the largest velocity change (else 0).
  template <bool Measure>
  double softSweep(StepContext& c, const Pass& p) {
    ConstraintSet& cs = *c.constraints;
    Row* rows = cs.rows.data();
    Vec3* v = c.v.data();
    Vec3* w = c.w.data();
    double change = 0;
    for (int ui = 0; ui < jointUnits_; ++ui) {
      const SolveUnit& u = cs.units[static_cast<size_t>(ui)];
      for (int q = 0; q < u.size; ++q) {
        const size_t k = static_cast<size_t>(u.first + q);
        Row& r = rows[k];
        const Update d = jointUpdate(r, k, p);
        change = std::max(change, solveRow<Measure>(r, rows, v, w, [&](double jv) { return -(d.a * jv + d.b) - d.si * r.lambda; }));
      }
    }
    change_.reset(c.workers().threads());
    change_.of(0) = change;  // the joints': uncoloured, one running maximum over the sweep, as before
    if (lanes_) {
      sweepLanes(c, p, Measure);
      return change_.largest();
    }
    for (int ph = 0; ph < phaseCount_; ++ph) {
      const Phase phase = phases_[ph];
      eachManifold(c, [&](size_t k, double& ch) {
        const FrictionDef& f = cs.frictions[k];
        Vec3 va = v[f.a], wa = w[f.a], vb = v[f.b], wb = w[f.b];
        double change = 0;  // in a register: the caller's running maximum is in memory
        if (phase != Phase::Friction) {
          const Vec3 dpA = dpV_[static_cast<size_t>(f.a)], dwA = dpW_[static_cast<size_t>(f.a)];
          const Vec3 dpB = dpV_[static_cast<size_t>(f.b)], dwB = dpW_[static_cast<size_t>(f.b)];
          const Softness& s = soft_[softOf_[static_cast<size_t>(f.firstNormal)]];
          for (int q = 0; q < f.normalCount; ++q) {
            const size_t kr = static_cast<size_t>(f.firstNormal + q);
            Row& r = rows[kr];
            const Update d = contactUpdate(r, kr, s, dpA, dwA, dpB, dwB, p);
            const double jv = rowVelocity(r, va, wa, vb, wb);
            const double next = std::clamp(r.lambda + (-(d.a * jv + d.b) - d.si * r.lambda), r.lo, r.hi);
            const double dl = next - r.lambda;
            r.lambda = next;
            r.pushed = r.pushed || next > 0;
            if (dl == 0) continue;
            applyImpulse(r, dl, va, wa, vb, wb);
            if (Measure && r.effMass > 0) change = std::max(change, std::abs(dl) / r.effMass);
          }
        }
        if (phase != Phase::Normals) {  // rigid in both passes: Δλ = -m_eff J̌v̌
          const SolveUnit& u = cs.units[static_cast<size_t>(f.frictionUnit)];
          solveFrictionUnit<Measure>(cs.couplings[static_cast<size_t>(u.block)], &rows[f.row], rows, va, wa, vb, wb, 0,
                                     1, change);
        }
        if (Measure) ch = std::max(ch, change);
        storeMoving(rows[f.row], va, wa, vb, wb, v, w);
      });
    }
    return change_.largest();
  }

  enum class Phase : unsigned char { Both, Normals, Friction };
  // A run's groups in groups_ [first, last), of its manifolds at laneOrder_[order ..] (count).
  struct Segment {
    size_t first, last, order, count;
    bool serial;  // the overflow: one manifold a group, in order on one thread
  };
  bool lanes_ = false;  // this step's manifolds solved in lanes (buildLanes)
  std::vector<lanes::Group> groups_;
  std::vector<lanes::ManifoldLanes> definitions_;  // buildLanes's, a thread
  std::vector<Segment> segments_;
  const int* laneOrder_ = nullptr;  // the manifolds in the order of the runs: colourOrder or runs_'
  LaneRuns runs_;
  static constexpr size_t kManifoldGrain = 32;  // manifolds of a colour a thread takes at a time
  static constexpr size_t kRunGrain = kManifoldGrain / lanes::kLanes;  // groups of a run a thread takes at a time
  static constexpr size_t kIslandGrain = 512;   // manifolds of whole islands a thread takes at a time
  bool scheduled_ = false;  // the groups by schedule_, not run by run (buildLanes)
  OrderedSchedule schedule_;
  Phase phases_[2] = {Phase::Both, Phase::Both};  // a sweep's passes over the manifolds (no allocation a step)
  int phaseCount_ = 1;
  int jointUnits_ = 0;
  ThreadMaxima change_;               // per thread: the sweep's largest velocity change

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

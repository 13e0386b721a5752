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
// Rows whose bias is not the baked (τ/κ)β¹ take it back each sub-step (IV.3.1.4):
//   velocity-level rows   β_row = c·target + J̌šʲ   (motors: c = 1, κ = 1; friction: target 0)
//   speculative contacts  β_row = f(βʲ)/κ + J̌šʲ,  βʲ = β¹ - J̌Σ_{k<j}v̌ᵏ, f(β) = β for β < 0 (closing
//                         a gap, not scaled by τ), τβ once penetrating: A4's row exactly.
// Joint Jacobians between sub-steps: every joint's (JacobianRefresh::EveryJoint, an extension), or the
// report's IV.4.1: only the 'stable' rows', recomputed while micro-iterating at the coordinates
// the running velocity predicts for the sub-step's end (JacobianRefresh::Stable).
#include "physics/constraints/joints.h"
#include "physics/step_arrays.h"
#include "physics/steppers/soft_lanes.h"
#include "physics/steppers/soft_lanes_fill.h"
#include "physics/steppers/stepper.h"

#include <algorithm>
#include <initializer_list>

namespace substep {

namespace {

// The lane groups a part of the step sweeps: [first, last) on the part's thread, or (scheduled)
// all of them by the stepper's OrderedSchedule on every thread.
struct GroupSpan {
  size_t first = 0, last = 0;
  bool scheduled = false;
};

class HavokActualStepper final : public Stepper {
 public:
  void stepVelocities(StepContext& c) override {
    ConstraintSet& cs = *c.constraints;
    const SolverSettings& st = *c.settings;
    const int n = c.n();
    const double dt = c.h() / n, kappa = st.kappa;
    const size_t nb = c.bodies();
    const bool stableOnly = st.jacobians == JacobianRefresh::Stable && !cs.joints.empty();
    c.stats = StepStats{};
    c.stats.rows = cs.rowCount();
    c.rowsHeld = cs.joints.empty();  // only joint rows are re-formulated between sub-steps

    splitPositionErrors(c);
    // Sized here; each body's sums zeroed, its sub-steps begun and ŵ¹ = v̌⁰ + ext (š¹ = 0) by its
    // block on the threads, not on the calling thread alone (as the soft step does).
    for (std::vector<Vec3>* sums : {&sumV_, &sumW_, &rawV_, &rawW_}) resizeRewritten(*sums, nb, c.workers());
    sizeSubSteps(c);
    if (stableOnly) collectStableRows(c);
    eachBodyBlock(c, [&](size_t first, size_t last) {
      for (std::vector<Vec3>* sums : {&sumV_, &sumW_, &rawV_, &rawW_})
        std::fill(sums->begin() + static_cast<ptrdiff_t>(first), sums->begin() + static_cast<ptrdiff_t>(last), Vec3::Zero());
      beginSubSteps(c, first, last);
      addExternal(c, dt, first, last);
    });
    // Islands share no body and no row, so each can go through all n sub-steps on its own, its
    // rows in cache: the same arithmetic in the same order within each island, so the same
    // numbers as all at once. The stable-row prediction works on every body at once: one part.
    // (A step that is one island, a pyramid, gets the whole without index lists from island(0).)
    // On more than one thread the islands are shared out: an island's rows and moving bodies are
    // its own, and static ones are only read (solves write back moving bodies alone). An island
    // too large for one thread (a pyramid, a heap) is shared out itself, unit by unit.
    WorkerPool& pool = c.workers();
    // In lanes (SolverSettings::lanes): warm, with the contact rows held (no joints) and a
    // manifold's normals a block (or one single row), the whole step at once, its manifolds eight
    // at a time in the runs of the step's order; the same numbers as island by island. Without
    // restitution and split impulses no contact row is stored: the groups are the rows. On more
    // threads, the whole step's groups by schedule_, or the groups of each part of whole islands
    // (a pile) through every sub-step on one thread.
    inLanes_ = !cs.laneGroups().empty();  // asked for by asksLaneGroups, granted by build()
    const int laneParts = inLanes_ ? cs.lanePartCount() : 0;
    c.stats.laneParts = laneParts;
    c.stats.laneScheduled = inLanes_ && pool.threads() > 1 && laneParts == 1;
    parts_.resize(static_cast<size_t>(std::max(pool.threads(), laneParts)));
    for (PartScratch& s : parts_) {
      s.residual = 0;
      if (!inLanes_) continue;  // else solvePart clears the lists it fills
      s.targets.clear();
      s.speculative.clear();
    }
    if (inLanes_) prepareLanes(c);  // lists the lanes' refreshed rows in parts_
    if (stableOnly || laneParts == 1) {
      const GroupSpan all{0, cs.laneGroups().size(), c.stats.laneScheduled};
      solvePart(c, cs.whole(nb), stableOnly, parts_[0], nullptr, all);
    } else if (inLanes_) {
      const std::vector<int>& first = cs.lanePartGroups();
      pool.forBlocks(static_cast<size_t>(laneParts), [&](size_t p, int) {
        const GroupSpan mine{static_cast<size_t>(first[p]), static_cast<size_t>(first[p + 1]), false};
        solvePart(c, cs.lanePart(static_cast<int>(p)), stableOnly, parts_[p], nullptr, mine);
      });
    } else if (pool.threads() == 1) {
      for (int k = 0; k < cs.islandCount(); ++k) solvePart(c, cs.island(k), stableOnly, parts_[0]);
    } else {
      // Islands of kLevelled units or more, one after another, each on every thread (UnitLevels
      // shares its sweeps out); then the others, each to one thread whole.
      whole_.clear();
      for (int k = 0; k < cs.islandCount(); ++k) {
        const ConstraintPart island = cs.island(k);
        if (island.units.count >= kLevelled && levels_.build(cs, island, nb)) solvePart(c, island, stableOnly, parts_[0], &levels_);
        else whole_.push_back(k);
      }
      // Runs of neighbouring islands a thread, not one: islands next to each other on two
      // threads share the cache lines of their boundary bodies (velocities, sums, sub-steps).
      // (One range or none runs here, on the calling thread: forBlocks.)
      const size_t grain = std::max<size_t>(1, whole_.size() / (16 * static_cast<size_t>(pool.threads())));
      pool.forRange(whole_.size(), grain, [&](size_t first, size_t last, int thread) {
        for (size_t k = first; k < last; ++k) solvePart(c, cs.island(whole_[k]), stableOnly, parts_[static_cast<size_t>(thread)]);
      });
    }
    for (const PartScratch& s : parts_) c.stats.residual = std::max(c.stats.residual, s.residual);
    if (pool.threads() > 1) {  // for the next step's asksLaneGroups
      int largest = 0;
      for (int k = 0; k < cs.islandCount(); ++k) largest = std::max(largest, cs.islandManifolds(k).count);
      oneLargeIsland_ = largest > 0 && 2 * static_cast<size_t>(largest) >= cs.frictions.size();
    }
    c.stats.iterations = n * st.iterations;
    const size_t last = static_cast<size_t>(n - 1) * nb;
    applyRestitution(c, &c.subV[last], &c.subW[last], kappa);
    solvePositionErrors(c, n * st.iterations, kappa);  // rows apply κM̌⁻¹J̌ᵀ; the split is of β, not β̄
  }

  void stepCoordinates(StepContext& c) override { stepCoordinatesSubStepped(c, RotationRule::Summed); }
  // build() grants the groups where the rows allow (warm, contact blocks, no joints; within L2
  // while the rows are stored beside them). On more threads, while the last step was mostly one
  // island, the whole step's: they then go by OrderedSchedule, a wait for each group's
  // predecessors, which costs less than the units' levels on one large island (a pyramid). Else
  // (a pile) in parts of whole islands, each part's groups swept on one thread with no wait:
  // kLanePartsAThread a thread, so that a thread done with its own takes what is left of another's.
  int asksLaneGroups(const SolverSettings& st, int threads) const override {
    if (!st.lanes) return 0;
    return threads == 1 || oneLargeIsland_ ? 1 : kLanePartsAThread * threads;
  }

 private:
  // Sub-steps 1..n of one part of the step (an island, or all of it).
  // What solving a part needs of its own: the rows it refreshes, its last sweep's largest change.
  struct Refreshed {
    Row* row;      // stored, or in lanes with the rows deferred a copy (laneRows_)
    double* lane;  // in lanes: its bias's lane, refreshed with it
    double base;   // targets: c·target; speculative rows: β¹
  };
  struct PartScratch {
    std::vector<Refreshed> targets, speculative;
    double residual = 0;
  };

  // With `levels` (built for this part), the part is shared out among the threads: its sweeps by
  // the levels, its passes over rows and bodies in blocks, the rows it refreshes listed in the
  // scratch of the thread that found them (parts_[thread]). Else all on this thread, in `scratch`.
  // In lanes, the groups in `groups` (scheduled: the sweeps by OrderedSchedule and the rest as
  // with levels), their rows listed by prepareLanes.
  void solvePart(StepContext& c, const ConstraintPart& part, bool stableOnly, PartScratch& scratch,
                 UnitLevels* levels = nullptr, GroupSpan groups = {}) {
    const bool shared = levels != nullptr || groups.scheduled;
    // f(row, the scratch that lists it) for the part's rows, f(body) for its bodies.
    const auto eachRow = [&](auto f) {
      eachIndex(c, part.rows, shared, [&](size_t k, int thread) { f(k, shared ? parts_[static_cast<size_t>(thread)] : scratch); });
    };
    const auto eachBody = [&](auto f) { eachIndex(c, part.bodies, shared, [&](size_t i, int) { f(i); }); };
    // f(scratch) for each scratch that lists the part's rows: on the threads if shared.
    const auto eachList = [&](auto f) {
      if (!shared) f(scratch);
      else c.workers().forBlocks(parts_.size(), [&](size_t t, int) { f(parts_[t]); });
    };
    ConstraintSet& cs = *c.constraints;
    const SolverSettings& st = *c.settings;
    const int n = c.n(), m = st.iterations;
    const double dt = c.h() / n, kappa = st.kappa, tau = st.tau;
    const BoxedScales scales = boxedScales(st);  // named, not bound: lambdas below capture them
    const double ratio = scales.ratio, invKappa = scales.invKappa;
    const size_t nb = c.bodies();
    // The boxed quantities (IV.4.2): β̄ = (τ/κ)β, bounds of λ̄ = bounds of λ over κ. Rows that take
    // their bias back each sub-step are listed with what they need.
    if (!inLanes_)
      eachList([](PartScratch& s) {
        s.targets.clear();
        s.speculative.clear();
      });
    if (groups.scheduled) {
      const std::vector<lanes::RigidGroup>& groups = cs.laneGroups();
      const std::vector<int>& runs = cs.laneRunGroups();
      size_t r = 0;  // the run of the group asked for (asked in order)
      schedule_.build(
          groups.size(), nb, c.workers().threads(), [&](size_t gi, auto follow) { lanes::eachMovingBody(groups[gi], follow); },
          [&](size_t gi) {
            while (static_cast<size_t>(runs[r + 1]) <= gi) ++r;
            return std::pair<size_t, size_t>(static_cast<size_t>(runs[r]), static_cast<size_t>(runs[r + 1]));
          });
    }
    const size_t laneBase = static_cast<size_t>(cs.contactFirstRow);
    eachRow([&](size_t k, PartScratch& s) {
      Row& r = cs.rows[k];
      const bool exact = r.velocityTarget && st.motorUnscaled;  // solved with κ = τ = 1
      listRefreshed(r, inLanes_ && k >= laneBase ? biasLane_[k - laneBase] : nullptr, exact, ratio, s);
      if (exact) return;
      r.bias *= ratio;
      if (r.normalRow < 0) {  // friction bounds are μ times the normal's λ̄ already
        r.lo *= invKappa;
        r.hi *= invKappa;
      }
      r.lambda *= invKappa;  // warm-started impulses, as λ̄
    });
    for (int j = 0; j < n; ++j) {
      if (inLanes_ && j == 0) {
        // Last step's λ from the lanes (which hold the rows' λ̄), row by row as applyRowImpulses;
        // the bodies' part of the warm start as for the stored rows (a part without rows).
        startSubStepImpulses(c, j, ConstraintPart{{}, {}, part.bodies, {}});
        lanes::RigidGroup* g = cs.laneGroups().data();
        passOverGroups(c, groups, [&](size_t first, size_t last, int) {
          lanes::kernel().warmRigid(g, first, last, c.v.data()->data(), c.w.data()->data());
        });
      } else {
        startSubStepImpulses(c, j, part);
      }
      // J̌šʲ and J̌Σv̌ᵏ: both sums are zero at the first sub-step, and š stays zero when τ = 0.
      const bool shifted = j > 0 && ratio != 0;
      eachList([&](PartScratch& s) {
        if (shifted)
          for (const Refreshed& f : s.targets) {
            Row& r = *f.row;
            r.bias = f.base + rowVelocity(r, sumV_.data(), sumW_.data());
            if (f.lane) *f.lane = r.bias;
          }
        for (const Refreshed& f : s.speculative) {
          Row& r = *f.row;
          const double shift = shifted ? rowVelocity(r, sumV_.data(), sumW_.data()) : 0.0;                // J̌šʲ
          const double beta = j > 0 ? f.base - rowVelocity(r, rawV_.data(), rawW_.data()) : f.base;  // βʲ by the update rule
          r.bias = (beta < 0 ? beta : tau * beta) * invKappa + shift;
          if (f.lane) *f.lane = r.bias;
        }
      });
      for (int i = 0; i < m && (inLanes_ || part.units.count > 0); ++i) {
        if (stableOnly) predictStableRows(c);
        const bool last = j + 1 == n && i + 1 == m;  // the step reports its last sweep's residual
        const double change = inLanes_ ? sweepLanes(c, groups, last)
                              : levels ? levels->sweep(cs, c.v, c.w, SweepScales{}, last, c.workers())
                                       : sweep(cs, part.units, c.v, c.w, SweepScales{}, last);
        if (last) scratch.residual = std::max(scratch.residual, change);
      }
      endSubStepImpulses(c, part);
      // v̌ʲ = ŵʲ - šʲ, recorded for s4; then šʲ⁺¹ and ŵʲ⁺¹.
      eachBody([&](size_t i) {
        const Vec3 v = c.v[i] - sumV_[i], w = c.w[i] - sumW_[i];
        c.subV[static_cast<size_t>(j) * nb + i] = v;
        c.subW[static_cast<size_t>(j) * nb + i] = w;
        sumV_[i] += ratio * v;
        sumW_[i] += ratio * w;
        rawV_[i] += v;
        rawW_[i] += w;
      });
      if (j + 1 < n) {
        const Vec3 ext = dt * c.model->gravity;
        eachBody([&](size_t i) {
          if (c.mass[i].invMass == 0) return;  // static, or asleep (World::updateSleep)
          const Vec3& w = c.subW[static_cast<size_t>(j) * nb + i];
          c.v[i] = c.subV[static_cast<size_t>(j) * nb + i] + ext + sumV_[i];
          c.w[i] = w + gyroscopicChange(w, c.model->bodies[i].inertia, dt, st.gyroscopic) + sumW_[i];
        });
        if (part.joints.count > 0) {
          advanceSubPoses(c, j, RotationRule::Summed, part.bodies);
          if (!stableOnly) cs.reformulateJoints(part.joints, c.subPoses, c.mass, dt, kappa);
        }
      }
    }
    if (inLanes_) emptyLanes(c, groups, kappa);  // before the rows' λ̄ = λ/κ is undone below
    eachRow([&](size_t q, PartScratch&) {
      Row& r = cs.rows[q];
      if (!(r.velocityTarget && st.motorUnscaled)) r.lambda *= kappa;  // kept as λ, for warm starting and overlays
    });
  }

  // f(index, thread) for every index of r: shared out among the threads (the calling one 0), else
  // all here as thread 0.
  template <class F>
  static void eachIndex(StepContext& c, const IndexRange& r, bool shared, F f) {
    if (!shared) {
      forEach(r, [&](size_t i) { f(i, 0); });
      return;
    }
    c.workers().forRange(static_cast<size_t>(r.count), 1024, [&](size_t first, size_t last, int thread) {
      for (size_t k = first; k < last; ++k) f(static_cast<size_t>(r[static_cast<int>(k)]), thread);
    });
  }

  // The rows whose bias is refreshed each sub-step, listed with what the refresh needs: a target
  // row (velocity level) its base c·target (friction: 0), which is its bias already and moves only
  // with J̌šʲ (zero while τ = 0); a speculative row β¹.
  // The boxed quantities' factors (IV.4.2): β̄ = (τ/κ)β, λ̄ = λ/κ (1/κ: a product a row instead
  // of up to three divisions).
  struct BoxedScales {
    double ratio, invKappa;
  };
  static BoxedScales boxedScales(const SolverSettings& st) { return {st.tau / st.kappa, 1 / st.kappa}; }
  static void listRefreshed(Row& r, double* lane, bool exact, double ratio, PartScratch& s) {
    if (r.velocityLevel && ratio != 0) s.targets.push_back({&r, lane, r.velocityTarget ? (exact ? 1 : ratio) * r.bias : 0});
    if (r.speculative) s.speculative.push_back({&r, lane, r.bias});
  }

  // The lanes ConstraintSet::build formulated (laneGroups) as the prologue leaves the rows: with
  // split impulses the normals' penetration split off (splitPositionErrors), then β̄ = (τ/κ)β and
  // λ̄ = λ/κ, the same operations. The rows refreshed between sub-steps get their bias's lane:
  // stored rows through biasLane_ (per contact row), deferred ones listed here from the lanes
  // before the scaling, as the stored rows' pass lists them (a copy of each, laneRows_, for J̌).
  void prepareLanes(StepContext& c) {
    ConstraintSet& cs = *c.constraints;
    const BoxedScales scales = boxedScales(*c.settings);
    const double ratio = scales.ratio, invKappa = scales.invKappa;
    std::vector<lanes::RigidGroup>& groups = cs.laneGroups();
    c.stats.laneRuns = cs.laneRunCount();
    c.stats.laneGroups = static_cast<int>(groups.size());
    const bool deferred = cs.contactRowsDeferred();
    if (deferred) resizeRewritten(cs.impulses, cs.frictions.size(), c.workers());  // for emptyLanes
    if (deferred) listLaneRows(c, ratio);
    else biasLane_.assign(cs.rows.size() - static_cast<size_t>(cs.contactFirstRow), nullptr);
    const size_t rowBase = static_cast<size_t>(cs.contactFirstRow);
    eachGroup(c, [&](lanes::RigidGroup& g) {
      if (c.settings->splitImpulse)
        for (int l = 0; l < g.count; ++l)
          for (int q = 0; q < g.points[l]; ++q) splitOff(g.normal[q].bias.x[l]);
      const auto scale = [&](lanes::RigidRowLanes& r) {
        for (int l = 0; l < lanes::kLanes; ++l) {
          r.bias.x[l] *= ratio;
          r.lambda.x[l] *= invKappa;
        }
      };
      for (lanes::RigidRowLanes& r : g.normal) scale(r);
      for (lanes::RigidRowLanes& r : g.friction) scale(r);
      if (!deferred)
        eachLaneRow(cs, g, [&](size_t row, lanes::RigidRowLanes& r, int l) { biasLane_[row - rowBase] = &r.bias.x[l]; });
    });
  }

  // f(group) for every lane group, on the threads (each writes only its own group's rows).
  template <class F>
  static void eachGroup(StepContext& c, F f) {
    std::vector<lanes::RigidGroup>& groups = c.constraints->laneGroups();
    c.workers().forRange(groups.size(), 64, [&](size_t first, size_t last, int) {
      for (size_t g = first; g < last; ++g) f(groups[g]);
    });
  }

  // Deferred: the lanes' speculative normals and (τ ≠ 0, friction exempt) friction rows, each
  // copied out as build() would have stored it and listed with its bias's lane.
  void listLaneRows(StepContext& c, double ratio) {
    ConstraintSet& cs = *c.constraints;
    const bool speculative = cs.speculativeContacts();
    const bool targets = ratio != 0 && c.settings->frictionExempt;
    laneRefs_.clear();
    for (lanes::RigidGroup& g : cs.laneGroups())
      for (int l = 0; l < g.count; ++l) {
        for (int q = 0; q < g.points[l]; ++q)
          if (apartAndSpeculative(g.normal[q].bias.x[l], speculative)) laneRefs_.push_back({&g, l, q, &g.normal[q].bias.x[l]});
        for (int i = 0; i < 3 && targets; ++i) laneRefs_.push_back({&g, l, g.points[l] + i, &g.friction[i].bias.x[l]});
      }
    // The copies on the threads (a collapsing pyramid has thousands of points apart), before any
    // is listed: the lists point into them.
    const size_t count = laneRefs_.size();
    laneRows_.resize(count);
    c.workers().forRange(count, 256, [&](size_t from, size_t to, int) {
      for (size_t k = from; k < to; ++k) cs.laneRow(*laneRefs_[k].g, laneRefs_[k].l, laneRefs_[k].q, laneRows_[k]);
    });
    // In parts of whole islands, each in its part's lists; else a share in each thread's lists:
    // on more threads the refreshes go on the threads, each thread its own lists.
    const std::vector<int>& partGroups = cs.lanePartGroups();
    const bool inParts = partGroups.size() > 2;
    const lanes::RigidGroup* first = cs.laneGroups().data();
    const size_t lists = parts_.size();
    size_t part = 0;
    for (size_t k = 0; k < count; ++k) {
      const LaneRef& ref = laneRefs_[k];
      while (inParts && ref.g - first >= partGroups[part + 1]) ++part;
      listRefreshed(laneRows_[k], ref.bias, false, ratio, parts_[inParts ? part : k * lists / count]);
    }
  }

  // f(its row, its lanes, lane) for every stored contact row of group g's lanes in use.
  template <class F>
  static void eachLaneRow(const ConstraintSet& cs, lanes::RigidGroup& g, F f) {
    for (int l = 0; l < g.count; ++l) {
      const FrictionDef& d = cs.frictions[static_cast<size_t>(g.manifold[l])];
      for (int q = 0; q < d.normalCount; ++q) f(static_cast<size_t>(d.firstNormal + q), g.normal[q], l);
      for (int i = 0; i < 3; ++i) f(static_cast<size_t>(d.row + i), g.friction[i], l);
    }
  }

  // The span's lanes' λ and pushed back to the rows, as the sweeps left them; with the rows
  // deferred, each manifold's impulses (λ = κλ̄, as the rows keep them) for storeImpulses.
  void emptyLanes(StepContext& c, const GroupSpan& groups, double kappa) {
    ConstraintSet& cs = *c.constraints;
    const bool deferred = cs.contactRowsDeferred();
    const auto empty = [&](lanes::RigidGroup& g) {
      if (!deferred) {
        eachLaneRow(cs, g, [&](size_t row, const lanes::RigidRowLanes& r, int l) {
          cs.rows[row].lambda = r.lambda.x[l];
          cs.rows[row].pushed = r.pushed.x[l] != 0;
        });
        return;
      }
      for (int l = 0; l < g.count; ++l) {
        const FrictionDef& fd = cs.frictions[static_cast<size_t>(g.manifold[l])];
        ConstraintSet::ManifoldImpulses& to = cs.impulses[static_cast<size_t>(g.manifold[l])];
        for (int q = 0; q < g.points[l]; ++q) to.normal[q] = g.normal[q].lambda.x[l] * kappa;
        const lanes::RigidRowLanes* f = g.friction;
        to.tangentInB = frictionImpulseInB(fd.qB, f[0].lambda.x[l] * kappa, lanes::laneVector(f[0].lin, l),
                                           f[1].lambda.x[l] * kappa, lanes::laneVector(f[1].lin, l));
        to.twist = f[2].lambda.x[l] * kappa;
      }
    };
    if (groups.scheduled) eachGroup(c, empty);
    else std::for_each(cs.laneGroups().begin() + static_cast<ptrdiff_t>(groups.first),
                       cs.laneGroups().begin() + static_cast<ptrdiff_t>(groups.last), empty);
  }

  // One sweep in lanes, in the units' order: every manifold's friction, then every block (split
  // order, warm), or each manifold's block and then its friction (manifold order).
  double sweepLanes(StepContext& c, const GroupSpan& groups, bool measure) {
    const lanes::Kernel& k = lanes::kernel();
    double* v = c.v.data()->data();
    double* w = c.w.data()->data();
    const lanes::BlockFallback fallback{&searchBlock, c.constraints};
    lanes::RigidGroup* g = c.constraints->laneGroups().data();
    double change = 0;  // unscheduled: the part's own, on its thread
    if (groups.scheduled) laneChange_.reset(c.workers().threads());
    const auto pass = [&](lanes::RigidPhase phase) {
      passOverGroups(c, groups, [&](size_t first, size_t last, int t) {
        double& mine = groups.scheduled ? laneChange_.of(t) : change;
        mine = std::max(mine, k.solveRigid(g, first, last, v, w, phase, measure, fallback));
      });
    };
    if (c.settings->contactOrder == ContactOrder::Manifold) {
      pass(lanes::RigidPhase::BlocksThenFriction);
    } else {
      pass(lanes::RigidPhase::Friction);
      pass(lanes::RigidPhase::Blocks);
    }
    return groups.scheduled ? laneChange_.largest() : change;
  }

  // f(first, last, thread) over the span's lane groups in order: all at once on this thread; or
  // scheduled, group by group on every thread (OrderedSchedule), each group once the groups
  // before it on its moving bodies are done, so that each body's rows are solved in the same
  // order on any number of threads.
  template <class F>
  void passOverGroups(StepContext& c, const GroupSpan& groups, F f) {
    if (groups.scheduled) schedule_.run(c.workers(), f);
    else f(groups.first, groups.last, 0);
  }
  static void searchBlock(void* set, int block, int points, const double* lambda, const double* b, double* delta) {
    ConstraintSet& cs = *static_cast<ConstraintSet*>(set);
    searchContactBlock(cs.laneBlock(block), points, lambda, b, delta);
  }

  // The 'stable' parts of every joint (joints.h: unbounded rows), for JacobianRefresh::Stable.
  void collectStableRows(const StepContext& c) {
    stable_.clear();
    for (const ConstraintSet::JointRef& ref : c.constraints->joints) {
      const JointLayout layout = jointLayout(c.model->joints[static_cast<size_t>(ref.joint)]);
      for (int p = 0; p < layout.parts; ++p)
        if (layout.part[p].stable) stable_.push_back({&ref, layout.part[p].offset, layout.part[p].size});
    }
  }

  // The 'next frame approximation' (IV.2.2, IV.3.2): stable rows' J̌ at the coordinates the
  // running velocity v̂ = ŵ - šʲ predicts for the end of sub-step j, from those the recorded
  // sub-steps reached (summed rotations, as s4 steps them). Their biases stay β̄ (IV.4.1).
  void predictStableRows(StepContext& c) {
    ConstraintSet& cs = *c.constraints;
    const double dt = c.h() / c.n();
    const size_t nb = c.bodies();
    predicted_.resize(nb);
    for (size_t i = 0; i < nb; ++i) {
      const Pose& at = c.subPoses[i];  // at t + j h/n (beginSubSteps, advanceSubPoses)
      if (c.model->bodies[i].isStatic) {
        predicted_[i] = at;
        continue;
      }
      const Vec3 v = c.v[i] - sumV_[i], w = c.w[i] - sumW_[i];
      predicted_[i].p = at.p + dt * v;
      predicted_[i].q = (at.q * Rq(dt * w)).normalized();
    }
    for (const StableRows& s : stable_) {
      const Joint& joint = c.model->joints[static_cast<size_t>(s.ref->joint)];
      scratch_.assign(static_cast<size_t>(s.ref->count), Row{});
      formulateJoint(joint, predicted_[static_cast<size_t>(joint.bodyA)], predicted_[static_cast<size_t>(joint.bodyB)],
                     dt, scratch_.data(), true);
      for (int k = 0; k < s.size; ++k) {
        Row& r = cs.rows[static_cast<size_t>(s.ref->first + s.offset + k)];
        const Row& fresh = scratch_[static_cast<size_t>(s.offset + k)];
        r.lin = fresh.lin, r.angA = fresh.angA, r.angB = fresh.angB;
      }
    }
    cs.refinishJoints(c.mass, c.settings->kappa);
  }

  struct StableRows {
    const ConstraintSet::JointRef* ref;
    int offset, size;
  };
  // Islands of fewer units go to one thread whole: on the 40-level pyramid's 3300 units, the
  // threads' waits for each other already cost about what sharing the sweeps saves.
  static constexpr int kLevelled = 2048;
  static constexpr int kLanePartsAThread = 4;
  bool inLanes_ = false;
  bool oneLargeIsland_ = false;  // the last step's largest island held half its manifolds or more
  OrderedSchedule schedule_;  // the lane groups on more threads
  ThreadMaxima laneChange_;  // in lanes: each thread's largest change in the sweep
  UnitLevels levels_;
  std::vector<int> whole_;  // the islands the threads take whole
  std::vector<double*> biasLane_;  // per stored contact row (from contactFirstRow): its bias's lane
  struct LaneRef {
    lanes::RigidGroup* g;
    int l, q;  // lane, row (laneRow's q)
    double* bias;
  };
  std::vector<LaneRef> laneRefs_;  // deferred: the lanes' rows refreshed between sub-steps ...
  std::vector<Row> laneRows_;      // ... and a copy of each (its J̌ for the refresh)
  std::vector<PartScratch> parts_;  // per thread
  std::vector<Vec3> sumV_, sumW_;  // 'SumVelocity' š, linear and angular
  std::vector<Vec3> rawV_, rawW_;  // Σ_{k<j} v̌ᵏ unscaled: speculative rows' βʲ
  std::vector<StableRows> stable_;
  std::vector<Pose> predicted_;
  std::vector<Row> scratch_;
};

}  // namespace

std::unique_ptr<Stepper> makeHavokActualStepper() { return std::make_unique<HavokActualStepper>(); }

}  // namespace substep

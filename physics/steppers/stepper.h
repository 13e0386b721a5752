// s3 and s4: one stepper per algorithm of the report, behind one interface.
//   a1_direct.cpp          Algorithm 1, essential stepping with a direct MLCP solve
//   a2_pgs.cpp             Algorithm 2, essential stepping, iterative (projected Gauss-Seidel, SOR)
//   a3_havok_conceptual.cpp, a4_havok_approximative.cpp, a5_havok_actual.cpp: sub-stepping
//   soft_step.cpp          not the report's: Box2D v3's soft step, an extension to compare against
#pragma once

#include "physics/constraints/constraint_set.h"
#include "physics/model.h"
#include "physics/parallel.h"
#include "physics/settings.h"
#include "physics/state.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

namespace substep {

struct StepStats {
  int iterations = 0;      // sweeps done (A2: until converged or capped; A3-A5: n·m; A1: 0)
  int directMethod = 0;    // A1: what answered: 1 Dantzig, 2 Lemke, 3 Gauss-Seidel and polish
  double residual = 0;     // A1: MLCP residual [m/s]; A2: largest row velocity change in the last sweep
  int rows = 0;
  int laneRuns = 0;        // soft, a5: the runs its manifolds were solved in, eight at a time (0: one at a time)
  int laneGroups = 0;      // soft, a5: the groups of eight of those runs (a group's lanes not in use cost as much)
  bool laneScheduled = false;  // soft, a5: the groups went by OrderedSchedule on the threads, not run by run
  int laneParts = 0;       // a5: parts of whole islands its groups were laid out in, each swept on one thread (1: the whole step)
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
  // Coordinates at t + j h/n during a step (A3-A5 re-formulate from them), and the running sums
  // Σ h/n v̌^k they are stepped with.
  std::vector<Pose> subPoses;
  std::vector<Vec3> sumV, sumW;
  // Split impulse: pseudo-velocities that move the coordinates in s4 without being momentum.
  std::vector<Vec3> pseudoV, pseudoW;
  std::vector<double> pseudoLambda;  // per contact point
  // Restitution changes the velocity the step ends with, not the one its coordinates were
  // stepped with (as Box2D applies it after the sub-steps): when set, s4 takes these as v̌'.
  std::vector<Vec3> endV, endW;
  bool bounced = false;
  // Warm starting sub-step j > 0 re-applies M̌⁻¹J̌ᵀλ of every row. When no row's J̌ changes between
  // sub-steps (the stepper sets rowsHeld), that is the velocity change sub-step j-1's rows made,
  // impV = v(after its sweeps) - startV(before its warm start), added per body instead of per row.
  bool rowsHeld = false;
  std::vector<Vec3> startV, startW, impV, impW;
  StepStats stats;
  WorkerPool* pool = nullptr;      // the step's threads

  // The step's threads; a context built without them (by hand, in a test) steps on one.
  WorkerPool& workers() const { return pool ? *pool : WorkerPool::callerOnly(); }
  double h() const { return settings->dt; }
  int n() const { return settings->substeps; }
  size_t bodies() const { return mass.size(); }
};

// f(first, last) over the step's bodies in blocks on its threads, for work that writes only each
// body's own entries.
template <class F>
void eachBodyBlock(StepContext& c, F f) {
  c.workers().forRange(c.bodies(), kBodyBlock, [&](size_t first, size_t last, int) { f(first, last); });
}

class Stepper {
 public:
  virtual ~Stepper() = default;
  virtual void stepVelocities(StepContext& c) = 0;   // s3
  virtual void stepCoordinates(StepContext& c) = 0;  // s4
  // Whether, under these settings, it formulates the contacts' rows itself as it solves them
  // (ConstraintSet::askDeferredContactRows).
  virtual bool formulatesContactRows(const SolverSettings&) const { return false; }
  // Whether, under these settings and on this many threads, it sweeps the contacts in the lanes
  // ConstraintSet::build lays out for it, and in how many parts of whole islands at most
  // (ConstraintSet::askLaneGroups: 0 none, 1 the whole step's).
  virtual int asksLaneGroups(const SolverSettings&, int /*threads*/) const { return 0; }
};

std::unique_ptr<Stepper> makeStepper(Algorithm a);

// --- A3 with approximations, for the tests that take A4 - A3 and A5 - A4 apart ----------------
// A4 differs from A3 at proc4:15 (Jacobians), proc4:16 (bias) and proc4:20 (rotation); A5 from
// A4 by IV.4.1's Jacobian approximation in the bias (IV.4.2's refactoring is exact). Each is a
// switch here, so that a test can run A3 with exactly one on. Not a solver setting: World makes
// its stepper from the algorithm, so a test reaches these through ScopedA3Approximations.
enum class BiasRule {
  Exact,              // proc3:15: βʲ⁺¹ from the coordinates at t + j h/n
  Update,             // proc4:16: βʲ⁺¹ = βʲ - J̌ʲv̌ʲ (position-level rows; IV.3.1)
  UpdateOneJacobian,  // IV.4.1, as A5 has it: βʲ⁺¹ = β¹ - J̌ʲ⁺¹ Σ_{k<=j} v̌ᵏ, one Jacobian for every term
};
struct Approximations {
  BiasRule bias = BiasRule::Exact;
  bool holdJacobians = false;   // proc4:15, IV.3.2: contacts keep J̌¹ over the step; joints are recomputed
  bool summedRotation = false;  // proc4:20: R_q(Σ h/n rv̌ᵏ), for the sub-steps' coordinates and s4
  bool none() const { return bias == BiasRule::Exact && !holdJacobians && !summedRotation; }
  static Approximations a4() { return {BiasRule::Update, true, true}; }
};
std::unique_ptr<Stepper> makeHavokConceptualStepper(const Approximations& a);
// While one lives, makeStepper(Algorithm::A3) on this thread makes A3 with `a` (they nest).
class ScopedA3Approximations {
 public:
  explicit ScopedA3Approximations(const Approximations& a);
  ~ScopedA3Approximations();
  ScopedA3Approximations(const ScopedA3Approximations&) = delete;
  ScopedA3Approximations& operator=(const ScopedA3Approximations&) = delete;

 private:
  Approximations a_;
  const Approximations* previous_;
};

// --- shared pieces ---------------------------------------------------------------------------

// Adds ext, the velocity the external forces give in time dt, to every dynamic body: gravity, and
// the gyroscopic term if the settings ask for it (the report's ext has none).
void addExternal(StepContext& c, double dt);
void addExternal(StepContext& c, double dt, size_t firstBody, size_t lastBody);  // bodies [first, last)
// The change of a body-frame angular velocity w over dt from ω × Iω alone (I the principal moments).
Vec3 gyroscopicChange(const Vec3& w, const Vec3& I, double dt, Gyroscopic mode);

// Applies every row's current λ to the velocities (warm starting): v̌ += M̌⁻¹J̌ᵀλ, in row order;
// or those of one part's rows.
void applyRowImpulses(ConstraintSet& cs, std::vector<Vec3>& v, std::vector<Vec3>& w);
void applyRowImpulses(ConstraintSet& cs, const IndexRange& rows, std::vector<Vec3>& v, std::vector<Vec3>& w);

// The factors of one sweep's row update  Δλ = m_eff (cBias β - cVel J̌ v̌):
// (ω, ω) for A2's PSOR, (τ, κ) for A3/A4, (1, 1) for A5 (factors baked in). Motors (velocity
// targets) take (biasTarget, velTarget): 1 unless the report's literal κ, τ on every row is
// asked for. A speculative contact closing its gap (β < 0) takes biasSpeculative: A2 ω, A3/A4 1
// (closing a gap is not an error correction, τ does not scale it), A5 1 (its bias is refreshed).
struct SweepScales {
  double bias = 1, vel = 1, biasTarget = 1, velTarget = 1, biasSpeculative = 1;
  static SweepScales psor(double omega) { return {omega, omega, omega, omega, omega}; }
  static SweepScales havok(const SolverSettings& s);  // A3/A4
};

// One row by Gauss-Seidel: dl = increment(J̌v̌) is added to λ within its bounds (friction: μ times
// its normals' current Σλ) and what was added is applied to the velocities; returns that velocity
// change |Δλ| / m_eff [m/s or rad/s]. The two bodies' velocities are read once: the compiler
// cannot tell the rows' doubles from the velocities' and would read them again.
template <bool Measure = true, class Increment>  // Measure false: returns 0
inline double solveRow(Row& r, const Row* rows, Vec3* v, Vec3* w, Increment increment) {
  Vec3 va = v[r.a], wa = w[r.a], vb = v[r.b], wb = w[r.b];
  double dl = increment(rowVelocity(r, va, wa, vb, wb));
  double lo = r.lo, hi = r.hi;
  if (r.normalRow >= 0) {
    const double ln = normalImpulse(r, rows);
    lo *= ln;
    hi *= ln;
  }
  const double next = std::clamp(r.lambda + dl, lo, hi);
  dl = next - r.lambda;
  r.lambda = next;
  r.pushed = r.pushed || next > 0;
  if (dl == 0) return 0;
  applyImpulse(r, dl, va, wa, vb, wb);
  storeMoving(r, va, wa, vb, wb, v, w);
  if (!Measure) return 0;
  return r.effMass > 0 ? std::abs(dl) / r.effMass : 0;
}

// change = max(change, |Δλ| / m_eff), dividing only for a new maximum (a division per row was a
// measurable part of a sweep; the result can differ from the plain form in its last bit).
inline void noteChange(double& change, double dl, double effMass) {
  if (effMass > 0 && std::abs(dl) > change * effMass) change = std::abs(dl) / effMass;
}

// A manifold's three friction rows (a Friction unit, r[0..2]) on the two bodies' velocities va..wb:
// Δλ = m_eff (cBias β - cVel J̌v̌) each, bounded by the same Σλn of the manifold's normals. J̌v̌ of
// all three is read at the unit's start; each row's Δλ then moves the later rows' by the coupling g
// instead of a velocity update and a twelve-term dot product.
template <bool Measure = true>  // false: leave change alone
__attribute__((always_inline)) inline void solveFrictionUnit(const FrictionCoupling& g, Row* r, const Row* rows, Vec3& va,
                                                             Vec3& wa, Vec3& vb, Vec3& wb, double cBias, double cVel,
                                                             double& change) {
  const double ln = normalImpulse(r[0], rows);
  double jv[3] = {rowVelocity(r[0], va, wa, vb, wb), rowVelocity(r[1], va, wa, vb, wb), rowVelocity(r[2], va, wa, vb, wb)};
  double d[3];
  for (int i = 0; i < 3; ++i) {
    if (i == 1) jv[1] += g.g10 * d[0];
    if (i == 2) jv[2] += g.g20 * d[0] + g.g21 * d[1];
    const double next = std::clamp(r[i].lambda + r[i].effMass * (cBias * r[i].bias - cVel * jv[i]), r[i].lo * ln, r[i].hi * ln);
    d[i] = next - r[i].lambda;
    r[i].lambda = next;
    r[i].pushed = r[i].pushed || next > 0;
  }
  for (int i = 0; i < 3; ++i) {
    if (d[i] == 0) continue;
    applyImpulse(r[i], d[i], va, wa, vb, wb);
    if (Measure) noteChange(change, d[i], r[i].effMass);
  }
}

// One Gauss-Seidel sweep over all solve units. For each unit
//   Δλ = m_eff (cBias β - cVel J̌ v̌),  λ <- proj(λ + Δλ),  v̌ += M̌⁻¹J̌ᵀ Δλ
// Returns the largest velocity change of a row, |Δλ| / m_eff [m/s or rad/s], or 0 unless measure
// (a sub-stepped step reports its last sweep's only). The second form sweeps the listed units only
// (one island's).
double sweep(ConstraintSet& cs, std::vector<Vec3>& v, std::vector<Vec3>& w, const SweepScales& k, bool measure = true);
double sweep(ConstraintSet& cs, const IndexRange& units, std::vector<Vec3>& v, std::vector<Vec3>& w, const SweepScales& k,
             bool measure = true);

// A part's solve units for a sweep shared out among threads, bit for bit the sequential sweep's.
// Each unit waits for its predecessors: the last unit before it (in the part's order) on each of
// the bodies it moves (storeMoving's test). Units that are not each other's predecessors through
// a chain share no moving body and commute exactly; so every unit, solved once its predecessors
// are, reads its bodies as the sequential sweep leaves them. The units are taken in order of
// level (a unit one level after its later predecessor; stable within a level), so that units
// side by side seldom wait for each other, in chunks claimed by the threads as they go; a unit
// waits only for its own predecessors, not for a whole level. Contacts only: a manifold's
// friction unit reads its normals' λ, which its block writes, and the two are ordered through a
// body they both move.
class UnitLevels {
 public:
  // False (and nothing to sweep) for a part with joints, or with a unit that moves no body.
  bool build(const ConstraintSet& cs, const ConstraintPart& part, size_t bodies);
  // sweep() over the part's units on the pool's threads: the same velocities and impulses. The
  // change measured is the largest of each thread's, each kept as noteChange keeps it.
  double sweep(ConstraintSet& cs, std::vector<Vec3>& v, std::vector<Vec3>& w, const SweepScales& k, bool measure,
               WorkerPool& pool);

  // Units a thread claims at once; a chunk's done marks fill one cache line.
  static constexpr int kChunk = 16;

 private:
  template <bool Measure>
  void sweepChunks(ConstraintSet& cs, std::vector<Vec3>& v, std::vector<Vec3>& w, const SweepScales& k, double& change);

  std::vector<int> order_;  // the units by level, each level in the part's order
  std::vector<int> before_;  // per place in order_: the places of its two predecessors (-1: none)
  std::vector<int> level_, last_, place_;  // scratch: each unit's level; each body's last unit
  struct alignas(64) Done {  // the sweep (epoch_) each unit of a chunk was last solved in
    std::atomic<uint32_t> sweep[kChunk];
  };
  std::vector<Done> done_;
  uint32_t epoch_ = 0;
  std::atomic<size_t> next_{0};  // the next place to claim
  ThreadMaxima change_;  // per thread: its largest change in the sweep
};

// A contact block of 2 to 4 points (BlockData) where neither nothing nor everything pushing fits
// (A5's lanes try both themselves): the increment Δ of its impulses λ for b = cBias β - cVel J̌v̌,
// with λ + Δ >= 0 and KΔ - b >= 0 complementary to it, as sweep's block solve finds it past those
// two tries. Reads the block's K and last set, not its K⁻¹.
void searchContactBlock(BlockData& d, int points, const double* lambda, const double* b, double* delta);

// Restitution (an extension: the report has none), after the velocity solve as Box2D does it:
// every contact point that was closing faster than the threshold at the step's start and pushed
// during the step gets the impulse that makes it separate at e times that speed (λ >= 0 still).
// v, w: the velocities the step ends with (A3-A5: the last sub-step's), copied into c.endV/endW
// when a point bounces, so that the coordinates are stepped without it (the body reaches the
// surface this step and leaves it the next). applyScale undoes the rows' scaled M̌⁻¹J̌ᵀ (A5's κ).
void applyRestitution(StepContext& c, const Vec3* v, const Vec3* w, double applyScale);
// The velocity the step ends with: c.endV if restitution set it, else `v`.
inline const Vec3& endVelocity(const StepContext& c, size_t i, const Vec3& v) { return c.bounced ? c.endV[i] : v; }
inline const Vec3& endAngularVelocity(const StepContext& c, size_t i, const Vec3& w) {
  return c.bounced ? c.endW[i] : w;
}

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

// Records the solver velocities as sub-step j's (0-based): every body's, or body i's.
void recordSubStep(StepContext& c, int j);
inline void recordSubStep(StepContext& c, int j, size_t i) {
  c.subV[static_cast<size_t>(j) * c.bodies() + i] = c.v[i];
  c.subW[static_cast<size_t>(j) * c.bodies() + i] = c.w[i];
}

// --- sub-stepping (A3-A5) ---------------------------------------------------------------------

// Starts the coordinates of the sub-steps at the step's (before the first sub-step) and sizes the
// warm start's per-body buffers (startV, impV, ...).
void beginSubSteps(StepContext& c);
// The same in two parts: the buffers sized, then bodies [first, last) started (a block of them on
// the step's threads).
void sizeSubSteps(StepContext& c);
void beginSubSteps(StepContext& c, size_t first, size_t last);
// Steps c.subPoses past recorded sub-step j with `rule`: the coordinates at t + (j+1) h/n, by
// the same formulas s4 uses (so after the last sub-step they are s4's result). Of every body, or
// of the listed ones.
void advanceSubPoses(StepContext& c, int j, RotationRule rule);
void advanceSubPoses(StepContext& c, int j, RotationRule rule, const IndexRange& bodies);
// Each sub-step solves a fresh MLCP (the report's algorithms do not warm start): λ = 0; with
// warm starting, the last sub-step's (or step's) λ instead, applied to the velocities: row by
// row, or, for j > 0 with c.rowsHeld, as the per-body change endSubStepImpulses recorded (the
// same sum in another order: equal to rounding). For one part of the step (its rows and bodies),
// or the whole.
void startSubStepImpulses(StepContext& c, int j, const ConstraintPart& part);
void startSubStepImpulses(StepContext& c, int j);
// After a sub-step's sweeps: records what its rows did to the velocities, for the next sub-step's
// warm start (only with warm starting and c.rowsHeld).
void endSubStepImpulses(StepContext& c, const ConstraintPart& part);
void endSubStepImpulses(StepContext& c);
// proc4:16, the bias update rule: β ← β - J̌ v̌ for every position-level row: not for friction
// or motors, whose β is a velocity (IV.3.1.4; docs/algorithms.md).
void updateBiases(ConstraintSet& cs, const std::vector<Vec3>& v, const std::vector<Vec3>& w);
// s3 of A3 and A4, which differ only between sub-steps (proc3:5-16, proc4:5-17): per sub-step j
// ext, the impulses to start from, m sweeps of J̌(κ v̌ + M̌⁻¹J̌ᵀλ) = τβ, the velocities recorded;
// then, unless j is the last, `between(j)`: A3 re-formulates, A4 updates the biases. Split
// impulse around it, as every algorithm has it.
void stepVelocitiesScaled(StepContext& c, const std::function<void(int j)>& between);

// --- split impulse (an extension; docs/algorithms.md) -----------------------------------------
// With settings.splitImpulse, takes each contact's penetration beyond the slop at the step's start
// out of its bias (Row::split), so the velocity problem the algorithm solves (and warm starts)
// carries no push-out; re-formulations subtract it again (ConstraintSet::reformulate).
void splitPositionErrors(StepContext& c);
// The part of a contact normal's bias split off (β > 0: a penetration), taken out of it.
inline double splitOff(double& bias) {
  const double split = std::max(bias, 0.0);
  bias -= split;
  return split;
}
// ... and corrects it instead with pseudo-velocities: `sweeps` Gauss-Seidel sweeps over the contact
// normal rows for J p = τ split / n, from p = 0 (never warm started). s4 moves the coordinates by
// h p; the velocities keep no trace of p. applyScale undoes the rows' scaled M̌⁻¹J̌ᵀ (A5's κ).
void solvePositionErrors(StepContext& c, int sweeps, double applyScale);

}  // namespace substep

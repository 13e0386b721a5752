// The soft step's contact solve, eight manifolds at a time (Box2D v3's wide contact solver,
// contact_solver.c, in 3D and in doubles). Eight manifolds that share no body that moves (of one
// colour, or of one run of the step's order: LaneRuns, lane_runs.h) are solved side by side,
// each in a lane of the same instructions: the sweep's work a manifold is the same, its
// instructions an eighth with AVX-512 (a quarter with AVX2 and the baseline, which solve a group
// as two parts of four). Each lane does what the soft step's one-manifold solve does
// (soft_step.cpp, softSweep), operation for operation and in the same order, with no fused
// multiply-add: every number is the same to the last bit, lanes or not (tests/test_lanes.cpp;
// the trajectory table holds every soft run).
//
// The data is laid out per group of eight manifolds, each field eight doubles (one a lane): built
// once a step with the rows' λ (SoftStepper::buildLanes), solved every sweep, the impulses written
// back to the rows when the step ends (with joints or cold, each sub-step). Warm and without
// joints or restitution, no contact row is stored: each manifold's are formulated as its lane is
// filled (in the world contact frame by the kernel, eight at once: Kernel::formulate), and its
// impulses go to ConstraintSet::impulses (ConstraintSet::askDeferredContactRows).
//
// The same kernel formulates the contact rows every other build stores (A1-A5, the soft step one
// manifold at a time or with joints): Kernel::formulateRows, called by ConstraintSet::build
// (physics/constraints/contact_lanes.cpp), in either contact frame, κ-scaled, with the contact
// blocks' K and K⁻¹; and A5 sweeps those groups in place (Kernel::solveRigid, RigidGroup).
//
// No Eigen here: the kernel is compiled three times, for AVX-512, for AVX2 and for the baseline
// x86-64 (SSE2), and the widest the processor runs is taken at run time. Inline functions shared
// with other files would be compiled for AVX-512 in one copy and could be the one the linker keeps.
#pragma once

#include <cstddef>
#include <cstdint>

namespace substep::lanes {

constexpr int kLanes = 8;
constexpr int kMaxNormals = 4;  // points a manifold keeps (reducePatch)

struct alignas(64) Doubles {
  double x[kLanes];
};
struct alignas(64) Mask {
  int64_t x[kLanes];  // all ones or zero
};

// One row in eight lanes: J̌ (lin on A's translation, -lin on B's; angA, angB in the bodies'
// frames), the effective mass [kg or kg m²] and λ. M̌⁻¹J̌ᵀ is not stored: it is the group's
// inverse masses times J̌, as finishRow makes it (the soft step's scale is 1), the same numbers.
struct RowLanes {
  Doubles lin[3], angA[3], angB[3];
  Doubles effMass, lambda;
  Mask pushed;  // λ was positive during this step
};
// A contact point's normal row: λ in [0, ∞) (formulateContact).
struct NormalLanes : RowLanes {
  Doubles c0;  // C at the step's start [m]
};
// A friction row: λ in [-μ Σλn, μ Σλn] (formulateFriction: β 0, bounds ±μ).
struct FrictionLanes : RowLanes {
  Doubles mu;  // [1, or m for the twist row]
};

struct Group {
  int count = 0;    // lanes in use (1 to 8); the others are zero rows that change nothing
  int normals = 0;  // the most normal rows of a lane
  int manifold[kLanes] = {};                  // the manifolds' indices (ConstraintSet::frictions)
  int a[kLanes] = {}, b[kLanes] = {};         // their bodies
  Doubles mA, mB;                             // inverse masses [1/kg]; zero: the body does not move
  Doubles invIA[3], invIB[3];                 // M̌⁻¹, rotational [1/(kg m²)]
  Doubles massScale, biasRate, impulseScale;  // the normals' softness (Softness)
  Doubles g10, g20, g21;                      // the friction rows' couplings (FrictionCoupling)
  NormalLanes normal[kMaxNormals];
  FrictionLanes friction[3];  // t1, t2, twist
};

// What formulating a group's manifolds reads, a lane each, in the world contact frame
// (ContactFrame::World: the normals and arms the narrowphase found): the bodies' frames and the
// points' and the friction's definitions (ConstraintSet::formulateManifold's, gathered by
// gatherManifold, soft_lanes_fill.h). A point a lane does not have, and a lane not in use (which
// the fill leaves as an earlier group left it), give zero rows.
struct ManifoldLanes {
  int normals[kLanes] = {};  // each lane's points (read in the lanes in use only)
  Doubles pA[3], RA[9], pB[3], RB[9];  // the bodies' frames: position [m], rotation (column-major)
  struct Point {
    Doubles localA[3], localB[3];  // on A in A's frame, on B in B's [m]
    Doubles n[3], armA[3], armB[3];  // world normal (B towards A), arms from the centres [m]
    Doubles lastLambda;  // warm start [N s]
  } point[kMaxNormals];
  Doubles n[3], armA[3], armB[3];  // friction: the manifold's normal, arms to the points' centroid
  Doubles lastImpulse[3];  // tangential warm start, in B's frame [N s]
  Doubles lastTwist;  // [N m s]
  Doubles mu, radius;  // friction coefficient; the points' mean distance from the centroid [m]
  // ContactFrame::Bodies (formulateRows only): each point's normal in B's frame, and the friction's
  // centroid on A and on B in their frames and normal in B's; the world fields above unread.
  Doubles localN[kMaxNormals][3];
  Doubles frictionLocalA[3], frictionLocalB[3], frictionLocalN[3];
};
// The formulation's constants: the time step the rows' β is for (ConstraintSet::build's) and the
// sub-step C⁰ = -β h is taken over (both h/n here) [s], the allowed penetration [m], and whether
// a point apart is speculative (else it holds nothing: λ 0).
struct Formulation {
  double hBuild, hSub, slop;
  bool speculative;
  // formulateRows only: the scale of M̌⁻¹J̌ᵀ (ConstraintSet::build's applyScale, > 0) and its
  // inverse as formBlock takes it; the frame; whether contact blocks' K and K⁻¹ are wanted; and
  // whether λ starts warm.
  double scale = 1, unscale = 1;
  bool bodiesFrame = false, blocks = false, warm = false;
};

// The inverse masses of a group's bodies, a lane each, for Kernel::formulateRows.
struct MassLanes {
  Doubles mA, mB;              // [1/kg]
  Doubles invIA[3], invIB[3];  // M̌⁻¹, rotational [1/(kg m²)]
};

// A sweep's pass: the solve (soft, with position feedback) or the relax (rigid, none).
struct Pass {
  bool useBias;
  double h;        // the sub-step [s]
  double pushOut;  // [m/s]
};

// A group of eight manifolds' stored rows, as Kernel::formulateRows makes them (formulateContact,
// formulateFriction, finishRow, frictionCoupling and formBlock side by side, the same numbers);
// ConstraintSet::build copies them to its rows, couplings and blocks, and, laid out in the runs of
// the step's order (ConstraintSet::laneGroups), A5 sweeps them in place: a manifold's Friction unit
// and its contact block (or, with one point, its single normal row) as sweep() solves them
// (stepper.cpp: solveUnit with A5's SweepScales, all 1; M̌⁻¹J̌ᵀ scaled by κ and stored), each lane
// operation for operation in the same order: the same numbers. λ and pushed go back to the rows
// when the step's sweeps are done; or, where nothing else reads them (no restitution, no split
// impulses), no contact row is stored and the impulses go to ConstraintSet::impulses.
// M̌⁻¹J̌ᵀ is not stored: the group's scaled inverse masses times J̌ (finishRow's products).
struct RigidRowLanes {
  Doubles lin[3], angA[3], angB[3];  // J̌
  Doubles effMass, bias, lambda;
  Mask pushed;
};
struct RigidGroup {
  int count = 0;   // lanes in use; the others are zero rows (no points) that change nothing
  int normals = 0;  // the most points of a lane
  int manifold[kLanes] = {}, a[kLanes] = {}, b[kLanes] = {};
  int points[kLanes] = {};
  int block[kLanes] = {};  // the lane's BlockData (ConstraintSet::blocks), with two or more points
  Doubles mA, mB;          // the rows' translational M̌⁻¹J̌ᵀ factors (scaled); zero: the body does not move
  Doubles invIA[3], invIB[3];  // M̌⁻¹, rotational: the rows' M̌⁻¹J̌ᵀ is scale (M̌⁻¹ ∘ ang) (finishRow's)
  double scale = 1;
  Mask single;             // one point: its normal is a single row (bounds [0, singleHi]), not a block
  Doubles singleHi;
  RigidRowLanes normal[kMaxNormals], friction[3];
  Doubles mu[3];  // the friction rows' bounds: ±mu Σλn
  Doubles g10, g20, g21;
  // The contact block's K⁻¹ (Formulation::blocks): of K regularised, identity outside the lane's
  // points; all zero where it failed.
  Doubles invK[kMaxNormals][kMaxNormals];
};
// ... and its K (unscaled, zero outside the points), which only the scalar search reads.
struct BlockLanes {
  Doubles K[kMaxNormals][kMaxNormals];
};
// A block lane that neither stays idle nor fits with every point pushing is solved by the scalar
// active-set search (stepper.cpp, solveContactBlock) on its BlockData.
struct BlockFallback {
  void (*solve)(void* context, int block, int points, const double* lambda, const double* b, double* delta);
  void* context;
};
enum class RigidPhase { Blocks, Friction, BlocksThenFriction };

// Velocities v, w: three doubles a body (world linear, body-frame angular); dpV, dpW: Σ h v̌ᵏ of
// the sub-steps so far, the same way.
struct Kernel {
  // Solves groups [first, last) in order. Returns the largest velocity change of a row when
  // measure is set (else 0).
  double (*solve)(Group* groups, size_t first, size_t last, double* v, double* w, const double* dpV, const double* dpW,
                  const Pass& pass, bool measure);
  // The warm start: each row's λ applied (v̌ += M̌⁻¹J̌ᵀλ), groups [first, last) in order.
  void (*warmStart)(const Group* groups, size_t first, size_t last, double* v, double* w);
  // The group's rows, C⁰, μ and couplings formulated from `in` as formulateManifold and finishRow
  // make them (scale 1), and λ warm: every number the same to the last bit. Reads the group's
  // count and inverse masses; lanes not in use, and points a lane does not have, are zero rows.
  void (*formulate)(const ManifoldLanes& in, Group& g, const Formulation& f);
  // Stored rows of eight manifolds, in the world or the bodies' frame, scaled by f.scale: every
  // row lane, mass, bound and block but the bodies and block indices (a lane's points from
  // in.normals, 0 for a lane not in use: zero rows and masses).
  void (*formulateRows)(const ManifoldLanes& in, const MassLanes& m, RigidGroup& out, BlockLanes& K,
                        const Formulation& f);
  // A5's sweep over groups [first, last) in order: each group's blocks, its friction, or both (in
  // that order). Returns the largest velocity change of a row when measure is set (else 0).
  double (*solveRigid)(RigidGroup* groups, size_t first, size_t last, double* v, double* w, RigidPhase phase,
                       bool measure, const BlockFallback& fallback);
  // A5's warm start: each row's λ applied (v̌ += M̌⁻¹J̌ᵀλ, A5's scaled M̌⁻¹J̌ᵀ), groups [first, last)
  // in order.
  void (*warmRigid)(const RigidGroup* groups, size_t first, size_t last, double* v, double* w);
  const char* name;  // "avx512", "avx2" or "sse2"
};

// f(body) for each body a group's solve writes, a Group's or a RigidGroup's: the moving ones (a
// lane's zero inverse mass: a body that does not move, which the kernels never write).
template <class G, class F>
void eachMovingBody(const G& g, F f) {
  for (int l = 0; l < g.count; ++l) {
    if (g.mA.x[l] != 0) f(g.a[l]);
    if (g.mB.x[l] != 0) f(g.b[l]);
  }
}

// The kernel the soft step uses: the widest this processor runs, unless useKernel chose another.
const Kernel& kernel();
// For the tests and the bench: solve with k from now on (null: the widest again).
void useKernel(const Kernel* k);
// Each, for the test that they agree.
const Kernel& sse2Kernel();
const Kernel& avx2Kernel();
const Kernel& avx512Kernel();
bool avx2Supported();
bool avx512Supported();

}  // namespace substep::lanes

// s2, constraint formulation: every joint and contact point of the step as rows of J̌ with their
// biases, in solve order (joints first, then contacts), grouped into solve units.
#pragma once

#include "physics/collision/manifold.h"
#include "physics/constraints/contact.h"
#include "physics/constraints/lane_runs.h"
#include "physics/constraints/row.h"
#include "physics/model.h"
#include "physics/parallel.h"
#include "physics/settings.h"
#include "physics/steppers/soft_lanes.h"

#include <cstdint>
#include <limits>
#include <vector>

namespace substep {

// A run of indices: listed (idx), or consecutive from `first` when idx is null.
struct IndexRange {
  const int* idx = nullptr;
  int first = 0, count = 0;
  int operator[](int k) const { return idx ? idx[k] : first + k; }
};

// f(i) for every index of r, as size_t; the test for a list is made once, not per index.
template <class F>
inline void forEach(const IndexRange& r, F f) {
  if (r.idx) {
    for (int k = 0; k < r.count; ++k) f(static_cast<size_t>(r.idx[k]));
  } else {
    for (int k = 0; k < r.count; ++k) f(static_cast<size_t>(r.first + k));
  }
}

// What a stepper can solve on its own, without reading or writing anything else: the solve units
// (in solve order), rows (in row order), bodies and joints of one island, or of the whole step.
struct ConstraintPart {
  IndexRange units, rows, bodies, joints;
};

class ConstraintSet {
 public:
  struct JointRef {
    int joint = 0;    // index in Model::joints
    int first = 0;    // its first row
    int count = 0;    // its rows this step (limits and motors may add or drop rows)
    int firstUnit = 0, units = 0;  // its solve units
  };

  // What a sub-step re-formulation recomputes.
  enum class Reformulation {
    Everything,      // A3 (proc3:15): J̌ and β of every constraint from the stepped coordinates
    JointJacobians,  // A4/A5 (IV.3.2): J̌ of the joints; biases follow the update rule; contacts held
    JointRows,       // the soft step: J̌ and β of the joints from the coordinates; contacts held
  };

  // Formulates everything at `poses` for time step h (the sub-step h/n under A3-A5). The rows'
  // M̌⁻¹J̌ᵀ are scaled by applyScale (κ under A5, else 1). Impulses start at zero, or at last
  // step's when warm starting.
  void build(const Model& model, const std::vector<Manifold>& manifolds, const std::vector<Pose>& poses,
             const std::vector<BodyMass>& mass, const SolverSettings& settings, double h, double applyScale);
  void reformulate(const std::vector<Pose>& poses, const std::vector<BodyMass>& mass, double h, Reformulation what,
                   double applyScale);
  // J̌ of the listed joints (JointRef indices) at `poses`, with their M̌⁻¹J̌ᵀ, effective masses and
  // blocks: Reformulation::JointJacobians for one part of the step.
  void reformulateJoints(const IndexRange& joints, const std::vector<Pose>& poses, const std::vector<BodyMass>& mass,
                         double h, double applyScale);
  // Recomputes M̌⁻¹J̌ᵀ, the effective masses and the blocks of the joint rows after their J̌
  // changed (A5's stable-row prediction).
  void refinishJoints(const std::vector<BodyMass>& mass, double applyScale);
  // Keeps this step's impulses: in the manifolds (for warm starting and overlays) and per joint.
  void storeImpulses(std::vector<Manifold>& manifolds);

  // Contact rows formulated where they are solved. The soft step in lanes can formulate each
  // manifold's rows as it fills the manifold's lane (formulateManifold) instead of build() writing
  // every contact row to `rows` and the lanes reading them back: asked before build(), which
  // grants it when nothing else reads a contact's row (no joints, no restitution, warm started).
  // Granted, `rows` holds no contact row (frictions' and contacts' row indices are where build()
  // would have put them), and the stepper leaves the step's impulses in `impulses` for
  // storeImpulses. The same numbers either way (docs/benchmarks.md). A5's lane groups, granted
  // without restitution or split impulses, hold their contact rows the same way (askLaneGroups).
  void askDeferredContactRows(bool ask) { deferAsked_ = ask; }
  bool contactRowsDeferred() const { return deferred_; }
  // Manifold k's rows as build() writes them to rows[frictions[k].firstNormal ..] (its points'
  // normal rows, then its three friction rows: normalCount + 3), and their friction coupling.
  // Valid from build() while the masses it was given live.
  void formulateManifold(size_t k, Row* out, FrictionCoupling& coupling) const;
  // Stored contact rows (and contact blocks' K and K⁻¹) formulated eight manifolds at a time in
  // SIMD lanes (on by default), or each manifold on its own: the same numbers (tests/test_lanes.cpp),
  // off for that test and to measure what the lanes buy.
  void formulateInLanes(bool on) { lanesAsked_ = on; }
  bool formulatedInLanes() const { return inLanes_; }  // the last build()'s contact rows were
  // A5's sweep in lanes: asked before build(), which grants it when the rows are formulated in
  // lanes, warm, with contact blocks and no joints. Granted, the groups are laid out in the runs
  // of the step's order (LaneRuns) and kept, rows and all, for the stepper to sweep in place
  // (laneGroups(); their block indices numbered); else there are none. Without restitution and
  // split impulses, which read the rows after the sweeps, the groups are the contact rows' only
  // copy (contactRowsDeferred(): no contact row or unit stored, each manifold's block in
  // laneBlock(k), the impulses left in `impulses`); else the rows are stored beside them.
  // Asked in `parts` > 1, with the rows deferred and the step more than one island, the groups are
  // laid out in up to that many parts of whole islands (in their order, about as many manifolds
  // each), every part's in its own runs: parts share no body, so each can be swept through the
  // step on its own thread, with no wait on another (lanePart). 0: no groups asked.
  void askLaneGroups(int parts) { laneGroupParts_ = parts; }
  std::vector<lanes::RigidGroup>& laneGroups() { return laneGroups_; }
  // Run r's groups (LaneRuns' runs): laneGroups()[laneRunGroups()[r] .. laneRunGroups()[r + 1]).
  const std::vector<int>& laneRunGroups() const { return laneRunGroups_; }
  // The parts the groups were laid out in (1: the whole step's runs); part p's groups are
  // laneGroups()[lanePartGroups()[p] .. lanePartGroups()[p + 1]), its islands lanePart(p).
  int lanePartCount() const { return std::max(0, static_cast<int>(lanePartGroups_.size()) - 1); }
  const std::vector<int>& lanePartGroups() const { return lanePartGroups_; }
  ConstraintPart lanePart(int p) const;
  // Row q of lane l of a lane group (its manifold's normal rows, then its three friction rows) as
  // build() stores it.
  void laneRow(const lanes::RigidGroup& g, int l, int q, Row& row) const;
  // The contact block a lane group's block index names: in `blocks`, or with the rows deferred,
  // manifold `block`'s own (its K and last set: its K⁻¹ is the group's alone).
  BlockData& laneBlock(int block) {
    return deferred_ ? laneBlocks_[static_cast<size_t>(block)] : blocks[static_cast<size_t>(block)];
  }
  int laneRunCount() const { return runCount_; }
  // Asks the cache for manifold k's rows, or deferred for what formulateManifold(k) reads (a caller
  // taking the manifolds out of their order does, a few ahead, when they outgrow the cache); and
  // how many bytes that is for all the manifolds.
  void prefetchManifold(size_t k) const;
  size_t manifoldBytes() const;
  // What formulateManifold reads besides manifold k's FrictionDef, for a formulation elsewhere (the
  // lanes): its points (in the manifolds build() was given, which they outlive), the bodies'
  // frames at the build's poses, the time step and slop β is for, and whether a point apart is
  // speculative.
  const ManifoldPoint* manifoldPoints(size_t k) const { return (*built_)[k].points; }
  const Frame& frame(int body) const { return frames_[static_cast<size_t>(body)]; }
  double formulationStep() const { return h_; }
  double slop() const { return slop_; }
  bool speculativeContacts() const { return speculative_; }
  struct ManifoldImpulses {
    double normal[kMaxManifoldPoints];  // each point's λ [N s]
    Vec3 tangentInB;                    // the friction impulse in B's frame (frictionImpulseInB) [N s]
    double twist;                       // [N m s]
  };
  std::vector<ManifoldImpulses> impulses;  // deferred: per manifold, written by the stepper
  // Rows of the step: in `rows`, or with the contact rows deferred where build() would have put them.
  int rowCount() const { return manifoldRow_.empty() ? static_cast<int>(rows.size()) : manifoldRow_.back(); }
  // Records each contact's normal velocity J̌v̌ at the step's start, for restitution.
  void recordApproach(const Vec3* v, const Vec3* w);

  std::vector<Row> rows;
  std::vector<SolveUnit> units;
  std::vector<BlockData> blocks;  // of the stable and contact blocks
  std::vector<FrictionCoupling> couplings;  // of the Friction units (their SolveUnit::block): manifold k's is k
  // One normal row per contact point; empty when the contact rows are deferred (then nothing in the
  // step reads a point's definition, and eachContact defines them from the manifolds).
  std::vector<ContactDef> contacts;
  std::vector<FrictionDef> frictions;  // three friction rows per manifold
  // The contacts (indices in `contacts`, in order) whose pair has restitution: the only ones
  // recordApproach and restitution read; on a pyramid, none.
  std::vector<int> bouncing;
  std::vector<JointRef> joints;
  int contactFirstRow = 0;             // rows from here on are contacts and friction

  // Islands: bodies that constraints join, directly or through other bodies (a static body joins
  // nothing), found by union-find over the manifolds and joints in build(). Dynamic bodies that touch nothing
  // are islands of their own. Numbered by their lowest body; each one's units, rows, bodies and
  // joints keep the step's order. Found for A5 (SolverSettings::islands; off: one island holds
  // everything) and for the soft step on more than one thread, uncoloured.
  int islandCount() const { return static_cast<int>(islands_.size()) - 1; }
  ConstraintPart island(int k) const { return islands(k, k + 1); }  // a single island is whole()
  ConstraintPart islands(int first, int last) const;  // islands [first, last) as one part
  ConstraintPart whole(size_t bodies) const;  // every unit, row, body (static ones too) and joint
  IndexRange islandManifolds(int k) const;    // island k's manifolds (in frictions), in the step's order

  // The soft step's colours (SolverSettings::colours; else empty): the manifolds ordered so that
  // no two of a colour share a body that moves, colour k's at colourOrder[colourStart[k] ..
  // colourStart[k + 1]) in the step's order, their rows laid out in this order; colour
  // kColours holds those that found none of the kColours (solved alone, last).
  static constexpr int kColours = 64, kDynamicColours = kColours - 4;
  std::vector<int> colourOrder, colourStart;

  // The threads build() and re-formulations share their work out on (null: the caller's alone).
  void setPool(WorkerPool* pool) { pool_ = pool; }

  // f(const ContactDef&) for every contact point of the last build(), in order: `contacts`, or
  // with the rows deferred each point defined from its manifold (build() was given, which it
  // reads) as build() would have stored it, but with no row (-1) and its last λ not known (NaN:
  // storeImpulses has written the step's own over it). Its bodies, anchors and normal, what
  // contactGap reads, are the same either way.
  template <class F>
  void eachContact(F f) const {
    if (!deferred_) {
      for (const ContactDef& c : contacts) f(c);
      return;
    }
    ContactDef c;
    for (const Manifold& m : *built_)
      for (int q = 0; q < m.count; ++q) {
        definePoint(m, m.points[q], worldFrame_, c);
        c.lastLambda = std::numeric_limits<double>::quiet_NaN();
        f(c);
      }
  }
  // Point p of manifold m as a ContactDef (its row -1: the caller's to number).
  static void definePoint(const Manifold& m, const ManifoldPoint& p, bool worldFrame, ContactDef& c);

  // Largest penetration of any contact point and largest joint error at `poses` [m].
  double maxPenetration(const std::vector<Pose>& poses) const;
  double maxJointError(const std::vector<Pose>& poses) const;

 private:
  void formulateJoint(const JointRef& ref, const std::vector<Pose>& poses, double h, bool jacobianOnly);
  // M̌⁻¹J̌ᵀ and effective masses of rows, and the blocks or couplings of units: of everything, of
  // one joint's rows and units, of a row range, of one unit.
  // contactsFinished: build() finished the manifolds' rows and couplings as it formulated them.
  void finishAll(const std::vector<BodyMass>& mass, double applyScale, bool contactsFinished);
  void finishJoint(const JointRef& ref, const std::vector<BodyMass>& mass, double applyScale);
  void finishRows(int firstRow, int lastRow, const std::vector<BodyMass>& mass, double applyScale);
  void finishUnit(SolveUnit& u, const std::vector<BodyMass>& mass, double applyScale);
  // Manifolds [first, last)'s rows, couplings and (blocksInLanes_) blocks into laneBlocks_, eight
  // at a time (contact_lanes.cpp).
  void formulateManifoldsInLanes(size_t first, size_t last);
  void formulateLaneGroups();  // the runs' groups into laneGroups_
  // The group of the listed manifolds (count of them) into g, and their rows, couplings and blocks.
  void formulateGroup(const int* manifolds, int count, const lanes::Formulation& f, lanes::ManifoldLanes& in,
                      lanes::RigidGroup& g);
  lanes::Formulation laneFormulation() const;
  bool lanesAsked_ = true, inLanes_ = false, blocksInLanes_ = false;
  int laneGroupParts_ = 0;  // askLaneGroups
  bool worldFrame_ = true;  // SolverSettings::contactFrame == World, for the lanes' formulation
  std::vector<LaneRuns> laneRuns_;  // each part's
  std::vector<lanes::RigidGroup> laneGroups_;
  std::vector<int> laneOrder_;       // the manifolds in the order of the parts' runs
  std::vector<int> laneGroupStart_;  // each group's first place in laneOrder_; one past the last
  std::vector<int> laneRunGroups_;   // each run's first group; one past the last
  std::vector<int> lanePartGroups_;  // each part's first group; one past the last
  std::vector<int> lanePartIslands_;  // each part's first island; one past the last (one part: empty)
  int runCount_ = 0;
  std::vector<BlockData> laneBlocks_;  // per manifold: its contact block, until finishAll numbers them

  const Model* model_ = nullptr;
  WorkerPool* pool_ = nullptr;
  WorkerPool& workers() const { return pool_ ? *pool_ : WorkerPool::callerOnly(); }  // the caller's alone without one
  // f(first, last) over [0, count) in ranges of `grain`, on the pool's threads when there is one.
  template <class F>
  void parallel(size_t count, size_t grain, F f) {
    if (pool_) pool_->forRange(count, grain, [&](size_t first, size_t last, int) { f(first, last); });
    else f(0, count);
  }
  std::vector<int> manifoldRow_, manifoldPoint_;  // per manifold: its first row and first point; one past the last
  // What formulateManifold reads of the last build().
  bool deferAsked_ = false, deferred_ = false;
  const std::vector<Manifold>* built_ = nullptr;  // build()'s manifolds
  // Asks the cache for what gatherManifold reads of manifold k: its FrictionDef and its points.
  void prefetchDefinition(size_t k) const;
  const std::vector<BodyMass>* mass_ = nullptr;
  double h_ = 0, applyScale_ = 1;
  bool warm_ = false, exempt_ = true;
  std::vector<unsigned char> bounces_;            // per manifold: its pair has restitution
  double slop_ = 0;
  bool stableBlocks_ = false, contactBlocks_ = false, speculative_ = true, motorUnscaled_ = true;
  std::vector<double> jointLambda_;  // per joint row, last step's impulses
  std::vector<int> jointLambdaFirst_;
  std::vector<Frame> frames_;  // the poses contacts are formulated at, as rotation matrices

  void findIslands(bool split);
  // The colours from colourKey_ (bodies: the model's count), or none.
  void colourManifolds(size_t bodies, bool on);
  // What the colouring reads of a manifold: its bodies, and whether each moves.
  static uint64_t colourKey(int a, int b, const std::vector<BodyMass>& mass);
  std::vector<uint64_t> colourUsed_;  // per body: the colours its manifolds took
  std::vector<unsigned char> colourOf_;
  std::vector<uint64_t> colourKey_, lastColourKey_;  // per manifold: this step's, and those the colours were found for
  // The order of the contact units: build() lays them out so, findIslands keeps it per island.
  enum class UnitOrder { NormalsFirst, FrictionFirst, Manifold };
  UnitOrder unitOrder_ = UnitOrder::NormalsFirst;
  // normals(f) and friction(f) for the manifolds listed (all, or the indices in `which`) in `order`.
  template <class Frictions, class Normals, class Friction>
  static void forEachContactUnit(Frictions& fs, const IndexRange& which, UnitOrder order, Normals normals,
                                 Friction friction) {
    auto each = [&](auto f) { forEach(which, [&](size_t k) { f(fs[k]); }); };
    switch (order) {
      case UnitOrder::NormalsFirst: each(normals), each(friction); break;
      case UnitOrder::FrictionFirst: each(friction), each(normals); break;
      case UnitOrder::Manifold:
        each([&](auto& f) {
          normals(f);
          friction(f);
        });
        break;
    }
  }
  template <class Frictions, class Normals, class Friction>
  static void forEachContactUnit(Frictions& fs, UnitOrder order, Normals normals, Friction friction) {
    forEachContactUnit(fs, IndexRange{nullptr, 0, static_cast<int>(fs.size())}, order, normals, friction);
  }
  struct Island {
    int units = 0, rows = 0, bodies = 0, joints = 0, manifolds = 0;  // where each of its lists starts
  };
  std::vector<Island> islands_, cursor_;  // islands_: and one past the last, for the ends
  std::vector<int> islandUnits_, islandRows_, islandBodies_, islandJoints_, islandManifolds_;
  std::vector<int> parent_, islandOf_;  // union-find over bodies; then each root's island
  // What the islands follow from (the settings that lay out units and rows, the model and its
  // body count, the joints, each manifold's bodies and points): this step's and that of the step
  // that found the lists. A model's bodies (which are static) do not change under a set.
  std::vector<uint64_t> islandKey_, lastIslandKey_;
};

}  // namespace substep

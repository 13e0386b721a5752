// The step pipeline, the report's four stages in order (IV.2.1):
//   s1 geometry        broadphase (FCL AABB tree), narrowphase (FCL + clipping), manifolds
//   s2 formulation     J̌ and β of every joint and contact point (for the step h/n)
//   s3 velocities      the stepper's velocity stepping (A1 .. A5)
//   s4 coordinates     the stepper's coordinate stepping
// Each stage is timed, so a run can say where its time went.
#pragma once

#include "physics/collision/broadphase.h"
#include "physics/collision/manifold.h"
#include "physics/collision/narrowphase.h"
#include "physics/collision/raycast.h"
#include "physics/constraints/constraint_set.h"
#include "physics/model.h"
#include "physics/parallel.h"
#include "physics/settings.h"
#include "physics/state.h"
#include "physics/steppers/stepper.h"

#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace substep {

struct StageTimes {
  double s1 = 0, s2 = 0, s3 = 0, s4 = 0;  // [s]
  double total() const { return s1 + s2 + s3 + s4; }
  StageTimes& operator+=(const StageTimes& o) {
    s1 += o.s1, s2 += o.s2, s3 += o.s3, s4 += o.s4;
    return *this;
  }
};

// Beyond these a state is taken as diverged: FCL's trees and the solvers lose all precision.
constexpr double kMaxCoordinate = 1e6;  // [m]
constexpr double kMaxSpeed = 1e6;       // [m/s] and [rad/s]

// A step the method cannot take on this scene with these settings (A1 beyond its size or its
// work budget): the settings are bad input for the scene, not a failure of the run.
struct Refused : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

struct StepReport {
  bool finite = true;    // false: the step stopped: the state diverged (non-finite or beyond the
                         // limits above), or too many bodies overlap (below)
  bool overloaded = false;  // ... because more bodies overlap than limits::kMaxPairsPerBody allows
  std::string problem;   // then: which body, and what
  StageTimes times;      // this step
  StepStats solver;
  int pairs = 0;         // broadphase pairs
  int manifolds = 0;
  int contactPoints = 0;
  int cachedPairs = 0;   // manifolds kept from the last step without a narrowphase query
  int asleep = 0;        // dynamic bodies asleep after the step (settings.sleep)
};

// Sleeping (settings.sleep; Box2D's rule): a body is still while below these; an island (bodies
// joined by touching contacts) whose bodies have all been still for kTimeToSleep stops stepping:
// its velocities are zeroed and it takes no part in the narrowphase, the formulation or the solve
// until a touching contact with an awake body, or a push, wakes it. Islands with joints stay awake.
constexpr double kSleepLinear = 0.05;                  // [m/s]
constexpr double kSleepAngular = 2 * 3.14159265358979 / 180;  // [rad/s]
constexpr double kTimeToSleep = 0.5;                   // [s]

class World {
 public:
  // The model must outlive the world.
  World(const Model& model, const SolverSettings& settings, const State& initial);
  ~World();

  // One step of length settings.dt; throws Refused when the algorithm cannot take it. Returns finite = false, with the body and the value in
  // `problem`, when a coordinate or velocity is not finite or beyond kMaxCoordinate/kMaxSpeed,
  // after the step or already before it (then without stepping); and with overloaded = true,
  // without stepping, when more pairs of bodies overlap than limits::kMaxPairsPerBody per body.
  const StepReport& step();

  // Changes the solver between steps, keeping the contact manifolds and their impulses (so warm
  // starting carries over). The algorithm may change too. Throws std::invalid_argument, changing
  // nothing, for settings no stepper takes (A1 with split impulse), as the constructor does.
  void setSettings(const SolverSettings& settings);

  const Model& model() const { return model_; }
  const SolverSettings& settings() const { return settings_; }
  const State& state() const { return state_; }
  const std::vector<Manifold>& manifolds() const { return manifolds_.manifolds(); }
  const ConstraintSet& constraints() const { return constraints_; }
  const StepReport& lastReport() const { return report_; }
  const StageTimes& totalTimes() const { return total_; }

  // Between steps: an impulse [N s] at a world point on a dynamic body (a user's push), or the
  // nearest body a ray meets (physics/collision/raycast.h). Throws std::invalid_argument for a
  // static body or a non-finite impulse.
  void applyImpulse(int body, const Vec3& impulse, const Vec3& worldPoint);  // wakes the body's island
  RayHit raycast(const Vec3& origin, const Vec3& direction, double maxDistance, bool dynamicOnly = true) const;

  // Measures of the current state.
  double kineticEnergy() const;    // Σ ½ m |v|² + ½ v̌ᵀ I v̌ [J]
  double potentialEnergy() const;  // Σ -m g·x [J]
  double maxPenetration() const;   // deepest contact point of the last step, at the current coordinates [m]
  double maxJointError() const;    // largest joint separation at the current coordinates [m]
  bool asleep(int body) const { return !asleep_.empty() && asleep_[static_cast<size_t>(body)] != 0; }

 private:
  bool diverged();                 // checks the state, fills report_.problem
  // f(i) for every body i, on the step's threads in blocks of kBodyBlock: for per-body work
  // that writes only body i's entries.
  template <class F>
  void eachBody(F f) {
    pool_->forRange(model_.bodies.size(), kBodyBlock, [&](size_t first, size_t last, int) {
      for (size_t i = first; i < last; ++i) f(i);
    });
  }
  std::vector<size_t> firstBad_;  // diverged(): each block's first body with a bad state
  bool geometry();                 // s1; false when overloaded
  void formulate();                // s2
  const std::vector<Manifold>& solvedManifolds();  // the manifolds s2 formulates
  bool dormant(int body) const;    // static, or asleep
  void wake(int body);             // its whole sleeping island
  void wakeTouched();              // islands a touching contact with an awake body reaches
  void updateSleep();              // after the step: still timers, islands that fall asleep

  const Model& model_;
  SolverSettings settings_;
  State state_;
  Broadphase broadphase_;
  std::unique_ptr<WorkerPool> pool_;       // settings_.threads (or fewer: WorkerPool)
  int poolAsked_ = 0;                      // the threads it was made for
  std::vector<Narrowphase> narrowphases_;  // one per thread
  ManifoldCache manifolds_;
  ConstraintSet constraints_;
  std::unique_ptr<Stepper> stepper_;
  StepContext ctx_;
  std::vector<std::pair<int, int>> pairs_;       // this step's, (A, B) as the manifold has them
  // s1's manifolds by block of pairs (a thread's share), then placed in the step's list.
  struct PairBlock {
    std::vector<Manifold> made;       // the block's new manifolds (narrowphase), in pair order
    // Each manifold of the block in pair order: k >= 0 last step's k-th kept, copied once when
    // placed (a manifold is 816 bytes), or aged where it is when the list stays in place; k < 0
    // made[-1 - k].
    std::vector<int> from;
    int cached = 0, fresh = 0;        // how many were kept from last step; their new points
    // Its kept manifolds stand in last step's list from place `shift` on as they do here; or
    // none is kept, or they stand otherwise (kMixed, never a place).
    static constexpr int kNoneKept = std::numeric_limits<int>::min(), kMixed = kNoneKept + 1;
    int shift = kNoneKept;
    int points = 0;                   // contact points of its manifolds
    size_t at = 0;                    // where the block's manifolds go in the step's list
    uint32_t firstId = 0;             // the id of its first new point, from the step's first
  };
  std::vector<PairBlock> pairBlocks_;  // storage kept between steps
  std::vector<double> reach_;  // per body: how far turning moves a point this step, plus half the margin [m]
  std::vector<Vec3> move_;     // per body: h v, its free-flight move this step without gravity [m]
  std::vector<Vec3> approachV_;  // per body: the velocity restitution measures approach speeds with
  // Sleeping (empty while settings.sleep is off): per body asleep, the island it fell asleep in
  // (its smallest body index) and how long it has been still [s]; the manifolds the step solves
  // (those with an awake body) and where each sits in manifolds_.
  std::vector<char> asleep_;
  std::vector<int> sleepIsland_;
  std::vector<double> still_;
  bool allAsleep_ = false;  // every dynamic body: the step has nothing to do
  std::vector<Manifold> active_;
  std::vector<size_t> activeAt_;
  StepReport report_;
  StageTimes total_;
};

}  // namespace substep

// One run: an engine stepped towards a planned number of steps, watched after every step by
// observers (metrics, a trajectory, progress, the failure watch, state hashes, frames), and ended
// by the plan, a step that diverges, an observer that asks (advice, Ctrl-C, energy blown up), or
// an algorithm that refuses the scene. `substep run`, the lab's runner, the bench, the render
// session and the server all step through it, so a run ends and is reported the same way
// everywhere.
//
//   WorldEngine engine(world);
//   RunDriver run(engine, steps);
//   run.add(trajectory).add(hashes);
//   const RunOutcome& o = run.run();      // or run.stepOnce() a step at a time
#pragma once

#include "physics/world.h"

#include <stdexcept>
#include <string>
#include <vector>

namespace substep {

// Contact depths of a step at the current coordinates: the deepest point and the sum of squares
// over the penetrating points.
struct ContactDepths {
  double deepest = 0, sumSquares = 0;
  int points = 0;
};
ContactDepths contactDepths(const World& world);

// What a run steps: substep's World, or a peer engine (lab/bullet_peer.h) whose state is read
// back into substep's State after each step.
class Engine {
 public:
  struct Step {
    bool finite = true;       // false: the state diverged, or the step could not be taken
    bool overloaded = false;  // ... because too many bodies overlap (World::step)
    std::string problem;      // then: which body, and what
  };
  virtual ~Engine() = default;
  // One step, the part that is timed; throws Refused. Then what became of it (not timed: a peer
  // reads its state back to tell).
  virtual void advance() = 0;
  virtual Step status() = 0;
  virtual const State& state() const = 0;
  virtual ContactDepths depths() const = 0;
  virtual const World* world() const { return nullptr; }  // substep's own, for its contacts and stages
};

class WorldEngine final : public Engine {
 public:
  explicit WorldEngine(World& w) : w_(w) {}
  void advance() override { w_.step(); }
  Step status() override;
  const State& state() const override { return w_.state(); }
  ContactDepths depths() const override { return contactDepths(w_); }
  const World* world() const override { return &w_; }

 private:
  World& w_;
};

// The step just taken, as observers see it.
struct StepRecord {
  long long step = 0;        // its number, from 1
  double seconds = 0;        // wall time of the engine's step [s]
  bool finite = true;
  const StepReport* report;  // substep's World only
};

struct RunOutcome {
  enum class End { Planned, Diverged, Stopped, Refused };
  End end = End::Planned;
  long long steps = 0;       // taken
  bool stepFailed = false;   // Diverged at a step the engine could not finish: non-finite, beyond the
                             // world's limits (not an observer's divergence, such as energy)
  bool overloaded = false;   // ... because too many bodies overlap
  std::string message;       // why it ended before the plan (see divergenceMessage)
  double seconds = 0;        // wall time inside the engine's steps [s]
};

// "the simulation diverged at step 12 (t = 0.200 s): <why>": the one wording of a run that ends
// because its state went wrong ("stopped" when the step could not be taken at all).
std::string divergenceMessage(long long step, double time, const std::string& why, bool stopped = false);

class RunObserver {
 public:
  virtual ~RunObserver() = default;
  virtual void begin(const Engine&) {}                      // the state at t = 0
  virtual void observe(const Engine&, const StepRecord&) {} // after each step, the diverged one too
  // Asked after observe(): a non-empty reason ends the run there.
  virtual std::string stop(const Engine&) { return {}; }
  // When the stop is a divergence (the energy blew up), its message is divergenceMessage's.
  virtual bool stopIsDivergence() const { return false; }
  virtual void end(const Engine&, const RunOutcome&) {}
};

class RunDriver {
 public:
  RunDriver(Engine& engine, long long steps) : engine_(engine), steps_(steps) {}
  RunDriver& add(RunObserver& o) {
    observers_.push_back(&o);
    return *this;
  }
  // Every step of the plan, or until the run ends. Calls begin() first and end() at the end.
  const RunOutcome& run();
  // One step (begin() before the first); false when the run has ended (then outcome() says why).
  bool stepOnce();
  void finish();  // end() for a run stepped by stepOnce()
  bool ended() const { return ended_; }
  const RunOutcome& outcome() const { return outcome_; }
  double lastStepSeconds() const { return last_; }
  long long planned() const { return steps_; }

 private:
  Engine& engine_;
  long long steps_;
  std::vector<RunObserver*> observers_;
  RunOutcome outcome_;
  bool begun_ = false, ended_ = false, finished_ = false;
  double last_ = 0;
};

}  // namespace substep

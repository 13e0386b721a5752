// Observers of a run (physics/run.h) that the commands share: the trajectory CSV, and the progress
// bar that also turns Ctrl-C into the run's end.
#pragma once

#include "app/common.h"
#include "physics/run.h"

#include <ostream>
#include <string>

namespace substep::app {

// step,time,body,px,py,pz,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz: one row per dynamic body at the start,
// at every `every`-th step and at the last planned one (angular velocity in the world frame).
class TrajectoryCsv final : public RunObserver {
 public:
  TrajectoryCsv(std::ostream& out, const Model& model, long long every, long long planned);
  void begin(const Engine& e) override { rows(e.state()); }
  void observe(const Engine& e, const StepRecord& r) override {
    if (r.finite && (r.step % every_ == 0 || r.step == planned_)) rows(e.state());
  }

 private:
  void rows(const State& s);
  std::ostream& out_;
  const Model& model_;
  long long every_, planned_;
};

// The progress bar of a long run (Progress: on a terminal only, not with -q), and its end on
// SIGINT or SIGTERM: the run stops with reason kInterrupted, and the command exits with 130.
class ProgressBar final : public RunObserver {
 public:
  static constexpr const char* kInterrupted = "interrupted";
  ProgressBar(const std::string& label, long long steps, bool show) : bar_(label, steps, show) {}
  void observe(const Engine&, const StepRecord& r) override { bar_.update(r.step); }
  std::string stop(const Engine&) override { return InterruptGuard::interrupted() ? kInterrupted : ""; }
  void end(const Engine&, const RunOutcome&) override { bar_.finish(); }

 private:
  Progress bar_;
  InterruptGuard interrupt_;
};

}  // namespace substep::app

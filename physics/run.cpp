#include "physics/run.h"

#include "physics/collision/manifold.h"

#include <chrono>
#include <cstdio>

namespace substep {

namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

ContactDepths contactDepths(const World& world) {
  ContactDepths p;
  const State& s = world.state();
  world.constraints().eachContact([&](const ContactDef& c) {
    const double depth = -contactGap(c, s.bodies[static_cast<size_t>(c.a)].pose(), s.bodies[static_cast<size_t>(c.b)].pose());
    if (!(depth > 0)) return;
    p.deepest = std::max(p.deepest, depth);
    p.sumSquares += depth * depth;
    ++p.points;
  });
  return p;
}

Engine::Step WorldEngine::status() {
  const StepReport& r = w_.lastReport();
  return Step{r.finite, r.overloaded, r.problem};
}

std::string divergenceMessage(long long step, double time, const std::string& why, bool stopped) {
  char t[48];
  std::snprintf(t, sizeof t, "%.3f", time);
  return std::string("the simulation ") + (stopped ? "stopped" : "diverged") + " at step " + std::to_string(step) +
         " (t = " + t + " s): " + why;
}

bool RunDriver::stepOnce() {
  if (ended_) return false;
  if (!begun_) {
    begun_ = true;
    for (RunObserver* o : observers_) o->begin(engine_);
  }
  if (outcome_.steps >= steps_) {
    ended_ = true;
    return false;
  }
  const auto t0 = Clock::now();
  try {
    engine_.advance();
  } catch (const Refused& e) {
    outcome_.end = RunOutcome::End::Refused;
    outcome_.message = e.what();
    ended_ = true;
    return false;
  }
  last_ = std::chrono::duration<double>(Clock::now() - t0).count();
  const Engine::Step s = engine_.status();
  outcome_.seconds += last_;
  const long long k = ++outcome_.steps;
  const World* w = engine_.world();
  const StepRecord rec{k, last_, s.finite, w ? &w->lastReport() : nullptr};
  for (RunObserver* o : observers_) o->observe(engine_, rec);
  if (!s.finite) {
    outcome_.end = RunOutcome::End::Diverged;
    outcome_.stepFailed = true;
    outcome_.overloaded = s.overloaded;
    outcome_.message = divergenceMessage(k, engine_.state().time, s.problem, s.overloaded);
    ended_ = true;
    return false;
  }
  for (RunObserver* o : observers_) {
    const std::string why = o->stop(engine_);
    if (why.empty()) continue;
    const bool diverged = o->stopIsDivergence();
    outcome_.end = diverged ? RunOutcome::End::Diverged : RunOutcome::End::Stopped;
    outcome_.message = diverged ? divergenceMessage(k, engine_.state().time, why) : why;
    ended_ = true;
    return false;
  }
  if (outcome_.steps >= steps_) ended_ = true;
  return !ended_;
}

void RunDriver::finish() {
  if (finished_) return;
  finished_ = true;
  if (!begun_) {
    begun_ = true;
    for (RunObserver* o : observers_) o->begin(engine_);
  }
  for (RunObserver* o : observers_) o->end(engine_, outcome_);
}

const RunOutcome& RunDriver::run() {
  while (stepOnce()) {
  }
  finish();
  return outcome_;
}

}  // namespace substep

#include "lab/runner.h"

#include "lab/peers.h"
#include "lab/record.h"
#include "physics/recording.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace substep::lab {

namespace {

// One pass: the mean step [s] and, for substep, the stages per step [s].
struct Pass {
  double mean = 0;
  std::optional<StageTimes> stages;
};

// States at frame times k / rate, taken when a step reaches them.
class Frames final : public RunObserver {
 public:
  Frames(double rate, std::vector<State>& out) : rate_(rate), out_(out) {}
  void begin(const Engine& e) override { take(e.state()); }
  void observe(const Engine& e, const StepRecord& r) override {
    if (r.finite) take(e.state());
  }

 private:
  void take(const State& s) {
    if (rate_ <= 0) return;
    while (static_cast<double>(out_.size()) / rate_ <= s.time + 1e-9) out_.push_back(s);
  }
  double rate_;
  std::vector<State>& out_;
};

// The setup's stop callback, asked with the metrics so far (advice stops a run that missed).
class StopWhen final : public RunObserver {
 public:
  StopWhen(const RunSetup& setup, const Probe& probe) : setup_(setup), probe_(probe) {}
  std::string stop(const Engine& e) override { return setup_.stop ? setup_.stop(probe_.metrics(), e.state().time) : ""; }

 private:
  const RunSetup& setup_;
  const Probe& probe_;
};

// The engine the method steps: substep's World, or a peer.
struct MethodEngine {
  std::unique_ptr<World> world;
  std::unique_ptr<WorldEngine> worldEngine;
  std::unique_ptr<Engine> peer;
  Engine& engine() { return peer ? *peer : static_cast<Engine&>(*worldEngine); }
};

MethodEngine makeEngine(const Scene& scene, const RunResult& r) {
  MethodEngine m;  // built outside the timed steps
  if (r.method.isPeer()) {
    m.peer = makePeerEngine(peerSettings(r.method, r.settings), scene.model, scene.initial);
  } else {
    m.world = std::make_unique<World>(scene.model, r.settings, scene.initial);
    m.worldEngine = std::make_unique<WorldEngine>(*m.world);
  }
  return m;
}

// The first pass is observed (metrics, frames, state hashes, the stop callback); the later ones
// time the same steps (`stepsDone` of the first) with nothing watching.
Pass runPass(const Scene& scene, RunResult& r, const RunSetup& setup, Probe* probe) {
  MethodEngine m;
  try {
    m = makeEngine(scene, r);
  } catch (const std::exception& e) {  // a peer that will not take what peerUnsupported() let through
    if (!r.method.isPeer()) throw;
    r.refused = true;
    r.stopped = "no " + peerDisplayName(r.method.peer) + " peer for this scene: " + e.what();
    return Pass{};
  }
  RunDriver run(m.engine(), probe ? r.steps : r.stepsDone);
  Frames frames(setup.frameRate, r.frames);
  StateHashes hashes(scene.model, r.steps);
  std::optional<StopWhen> stopWhen;
  std::optional<RecordingWriter> writer;
  std::optional<RecordingObserver> recorder;
  if (probe) {
    stopWhen.emplace(setup, *probe);
    run.add(*probe).add(frames).add(hashes).add(*stopWhen);
    if (!setup.recording.empty()) {
      const RecordingPanel panel{r.method.text, recordSettingsJson(r.method, r.settings), r.method.text, r.method.isPeer() ? r.method.peer : "substep"};
      writer.emplace(setup.recording, recordingMeta(scene, {panel}, setup.recordEvery, r.steps));
      recorder.emplace(*writer, scene.model, 0, setup.recordEvery, r.steps);
      run.add(*recorder);
    }
  }
  const RunOutcome& o = run.run();
  if (writer && (o.end == RunOutcome::End::Planned || o.end == RunOutcome::End::Diverged)) {
    writer->commit();  // as `substep run` writes its outputs: a divergence keeps the steps before it
    r.recording = setup.recording;
  }
  if (probe) {
    r.stepsDone = o.steps;
    r.time = m.engine().state().time;
    r.hashes = hashes.hashes();
    r.finite = !o.stepFailed;
    switch (o.end) {
      case RunOutcome::End::Planned: break;
      case RunOutcome::End::Refused:
        r.refused = true;
        r.stopped = o.message;
        break;
      case RunOutcome::End::Diverged:
        r.diverged = true;
        r.stopped = o.message;
        break;
      case RunOutcome::End::Stopped: r.stoppedEarly = o.message; break;
    }
  }
  Pass p;
  const double n = static_cast<double>(std::max(1LL, o.steps));
  p.mean = o.seconds / n;
  if (m.world) {
    const StageTimes& t = m.world->totalTimes();
    p.stages = StageTimes{t.s1 / n, t.s2 / n, t.s3 / n, t.s4 / n};
  }
  return p;
}

}  // namespace

RunResult runMethod(const Scene& scene, const Method& method, const RunSetup& setup) {
  RunResult r;
  r.method = method;
  r.settings = methodSettings(method, scene, setup.dt);  // throws std::invalid_argument
  r.steps = static_cast<long long>(std::ceil(setup.seconds / r.settings.dt - 1e-9));
  if (method.isPeer()) {
    const std::string why = peerUnsupported(method.peer, scene.model, scene.initial);
    if (!why.empty()) {
      r.refused = true;
      r.stopped = "no " + peerDisplayName(method.peer) + " peer for this scene: " + why;
      return r;
    }
  } else {
    World probeWorld(scene.model, r.settings, scene.initial);  // settings the World refuses throw here
  }
  Probe probe(scene, setup.seconds, setup.reference);
  std::vector<Pass> passes;
  for (int rep = 0; rep < std::max(1, setup.repeat); ++rep) {
    passes.push_back(runPass(scene, r, setup, rep == 0 ? &probe : nullptr));
    if (rep == 0 && (r.refused || !r.stoppedEarly.empty())) break;  // nothing to time again
  }
  r.metrics = probe.finish();
  // The median repeat by total, its stages with it (with an even count, the two middle averaged).
  std::vector<size_t> order(passes.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return passes[a].mean < passes[b].mean; });
  const size_t n = passes.size();
  const Pass& lo = passes[order[(n - 1) / 2]];
  const Pass& hi = passes[order[n / 2]];
  r.cost.msPerStep = 1e3 * 0.5 * (lo.mean + hi.mean);
  if (lo.stages && hi.stages)
    r.cost.stages = StageTimes{500 * (lo.stages->s1 + hi.stages->s1), 500 * (lo.stages->s2 + hi.stages->s2),
                               500 * (lo.stages->s3 + hi.stages->s3), 500 * (lo.stages->s4 + hi.stages->s4)};
  for (const Pass& p : passes) r.cost.repeats.push_back(1e3 * p.mean);
  return r;
}

}  // namespace substep::lab

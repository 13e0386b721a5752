#include "lab/runner.h"

#include "lab/bullet_peer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace substep::lab {

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// One timed pass: the mean step [s] and, for substep, the stages per step [s].
struct Pass {
  double mean = 0;
  std::optional<StageTimes> stages;
};

// States at frame times k / rate, taken when a step reaches them.
class Frames {
 public:
  Frames(double rate, std::vector<State>& out) : rate_(rate), out_(out) {}
  void take(const State& s) {
    if (rate_ <= 0) return;
    while (static_cast<double>(out_.size()) / rate_ <= s.time + 1e-9) out_.push_back(s);
  }

 private:
  double rate_;
  std::vector<State>& out_;
};

std::string divergedText(double t) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", t);
  return std::string("diverged at t = ") + buf +
         " s: the mechanical energy grew beyond 100 times the energy that lifts every body by its size";
}

// The substep World: the first pass observed, stopped early if asked; the later passes time the
// same steps (`steps`: the first pass's count).
Pass runWorld(const Scene& scene, RunResult& r, const RunSetup& setup, Probe* probe) {
  World world(scene.model, r.settings, scene.initial);  // outside the timed loop
  Frames frames(probe ? setup.frameRate : 0, r.frames);
  frames.take(world.state());
  double timed = 0;
  long long done = 0;
  const long long steps = probe ? r.steps : r.stepsDone;
  for (long long k = 0; k < steps; ++k) {
    const auto t0 = Clock::now();
    const StepReport* rep = nullptr;
    try {
      rep = &world.step();
    } catch (const std::runtime_error& e) {  // A1 beyond its size or work budget
      if (probe) {
        r.refused = true;
        r.stopped = e.what();
      }
      break;
    }
    timed += since(t0);
    ++done;
    if (!probe) continue;
    r.stepsDone = done;
    r.time = world.state().time;
    probe->observe(world.state(), worldPenetration(world), rep->finite);
    if (!rep->finite) {
      r.finite = false;
      r.diverged = true;
      char t[32];
      std::snprintf(t, sizeof t, "%.2f", world.state().time);
      r.stopped = (rep->overloaded ? "stopped at step " : "diverged at step ") + std::to_string(k + 1) + " (t = " + t +
                  " s): " + rep->problem;
      break;
    }
    if (probe->diverged()) {
      r.diverged = true;
      r.stopped = divergedText(world.state().time);
      break;
    }
    frames.take(world.state());
    if (setup.stop) {
      r.stoppedEarly = setup.stop(probe->metrics(), world.state().time);
      if (!r.stoppedEarly.empty()) break;
    }
  }
  Pass p;
  const double n = static_cast<double>(std::max(1LL, done));
  p.mean = timed / n;
  const StageTimes& t = world.totalTimes();
  p.stages = StageTimes{t.s1 / n, t.s2 / n, t.s3 / n, t.s4 / n};
  return p;
}

Pass runBullet(const Scene& scene, RunResult& r, const RunSetup& setup, Probe* probe) {
  const BulletSettings b{r.settings.dt, r.settings.iterations, r.settings.gyroscopic != Gyroscopic::None};
  BulletPeer peer(scene.model, scene.initial, b.dt, b.iterations, b.gyroscopic);  // outside the timed loop
  Frames frames(probe ? setup.frameRate : 0, r.frames);
  frames.take(scene.initial);
  State s = scene.initial;
  double timed = 0;
  long long done = 0;
  const long long steps = probe ? r.steps : r.stepsDone;
  for (long long k = 0; k < steps; ++k) {
    const auto t0 = Clock::now();
    peer.step();
    timed += since(t0);
    ++done;
    if (!probe) continue;
    peer.state(s);
    s.time = static_cast<double>(k + 1) * b.dt;
    s.step = k + 1;
    r.stepsDone = done;
    r.time = s.time;
    const bool finite = s.finite();
    const BulletPeer::Penetration bp = peer.penetration();
    probe->observe(s, Penetration{bp.deepest, bp.sumSquares, bp.points}, finite);
    if (!finite) {
      r.finite = false;
      r.diverged = true;
      r.stopped = "diverged at step " + std::to_string(k + 1) + ": a Bullet body's state is not finite";
      break;
    }
    if (probe->diverged()) {
      r.diverged = true;
      r.stopped = divergedText(s.time);
      break;
    }
    frames.take(s);
    if (setup.stop) {
      r.stoppedEarly = setup.stop(probe->metrics(), s.time);
      if (!r.stoppedEarly.empty()) break;
    }
  }
  Pass p;
  p.mean = timed / static_cast<double>(std::max(1LL, done));
  return p;
}

}  // namespace

Penetration worldPenetration(const World& world) {
  Penetration p;
  const State& s = world.state();
  for (const ContactDef& c : world.constraints().contacts) {
    const double depth = -contactGap(c, s.bodies[static_cast<size_t>(c.a)].pose(), s.bodies[static_cast<size_t>(c.b)].pose());
    if (!(depth > 0)) continue;
    p.deepest = std::max(p.deepest, depth);
    p.sumSquares += depth * depth;
    ++p.points;
  }
  return p;
}

RunResult runMethod(const Scene& scene, const Method& method, const RunSetup& setup) {
  RunResult r;
  r.method = method;
  r.settings = methodSettings(method, scene, setup.dt);  // throws std::invalid_argument
  r.steps = static_cast<long long>(std::ceil(setup.seconds / r.settings.dt - 1e-9));
  if (method.isBullet()) {
    const std::string why = bulletUnsupported(scene.model);
    if (!why.empty()) {
      r.refused = true;
      r.stopped = "no Bullet peer for this scene: " + why;
      return r;
    }
  } else {
    World probeWorld(scene.model, r.settings, scene.initial);  // settings the World refuses throw here
  }
  Probe probe(scene, setup.seconds, setup.reference);
  std::vector<Pass> passes;
  for (int rep = 0; rep < std::max(1, setup.repeat); ++rep) {
    Probe* observe = rep == 0 ? &probe : nullptr;
    passes.push_back(method.isBullet() ? runBullet(scene, r, setup, observe) : runWorld(scene, r, setup, observe));
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

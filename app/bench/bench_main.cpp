// substep-bench: how fast each algorithm steps the benchmark scenes, where the time goes
// (s1 geometry, s2 formulation, s3 velocities, s4 coordinates), and what the speed buys
// (contact points, how far the bodies moved), next to the peers (Bullet, ODE, MuJoCo: lab/peers.h)
// stepping the same scene in the same process. See docs/benchmarks.md.
//
// Method: for each repeat, each scene and each case, a fresh World (or Bullet world) is built
// from the scene's initial state outside the timed loop, then stepped N times; every call of
// World::step() (or btDiscreteDynamicsWorld::stepSimulation(dt, 0)) is timed on its own with
// steady_clock, all N steps, no warm-up step left out. A run's time is the mean over its steps;
// the reported figure is the median over the repeats (the run with the median total, its stage
// split with it; with an even count the two middle runs averaged). Repeats are interleaved
// (repeat 1 of every case, then repeat 2, ...) so slow drift of the machine spreads over all
// cases. Single-threaded, unless --threads N adds each substep case on N threads (the speed-up,
// and the end states' hashes equal); --core-check then also times it on one thread pinned to
// each core, for the speed-up the cores' own speeds allow (app/bench/core_bound.h), and how long
// the first two cores take to hand a cache line over just before each N-thread run
// (app/bench/core_handover.h).
//
// What the speed buys is measured the same way for both engines, with our own definitions:
// displacement from the start (after 1 s and at the end), the fastest body, the joints' anchor
// separation and how far joint angles are beyond their limits (physics/constraints/joints.h).
#include "lab/bullet_peer.h"
#include "lab/method.h"
#include "lab/peers.h"
#include "lab/chart.h"
#include "lab/provenance.h"
#include "app/bench/bench_stats.h"
#include "app/bench/core_bound.h"
#include "app/bench/core_handover.h"
#include "app/bench/ratio_text.h"
#include "app/common.h"
#include "physics/constraints/joints.h"
#include "physics/scene_file.h"
#include "physics/settings.h"
#include "physics/settings_json.h"
#include "physics/failure.h"
#include "physics/run.h"
#include "physics/state_hash.h"
#include "physics/steppers/soft_lanes.h"
#include "physics/world.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <sched.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

#ifndef SUBSTEP_BUILD_TYPE
#define SUBSTEP_BUILD_TYPE "unknown"
#endif

namespace substep::bench {
namespace {

using lab::bulletVersion;
using lab::cpuModel;
using lab::loadAverage;
using lab::sourceState;
using lab::utcNow;

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Exit status as the substep program has it (app/common.h), and 4: a case not repeatable.
using app::kExitBadInput;
using app::kExitNonFinite;
constexpr int kExitNotRepeatable = 4;
using app::UsageError;

// --- the cases --------------------------------------------------------------------------------

enum class EngineKind { Substep, Peer };

struct Case {
  const char* id;          // its name for --algos
  const char* label;       // its name in the table
  const char* spec;        // the method (physics/settings.h); the scene gives only the time step
  bool byDefault;          // run when --algos is not given
  EngineKind engine() const { return peer().empty() ? EngineKind::Substep : EngineKind::Peer; }
  std::string peer() const { return expandMethodSpec(spec).at(0).peer; }  // "" for substep's
  // Its settings at the scene's h: the method's own over the algorithm's defaults, so that the
  // scene's solver block cannot change what a case means.
  SolverSettings settings(double dt) const {
    SolverOverrides o = expandMethodSpec(spec).at(0).overrides;
    if (engine() == EngineKind::Peer) {
      o.set(&SolverSettings::algorithm, Algorithm::A2);  // n stays 1
      o.set(&SolverSettings::gyroscopic, Gyroscopic::Implicit);  // Bullet's and ODE's own term, on
    }
    o.set(&SolverSettings::dt, dt);
    return resolve(o);
  }
};

// Every case the benchmark knows, in table order. Adding one, or running one by default, is an
// edit of one line here. Equal solver work: a2-m4 makes 4 Gauss-Seidel sweeps per step, as
// a3/a4/a5 at n = 4 sub-steps of m = 1 sweep do. a5-stack has pyramid.json's settings, what holds
// the pyramid. soft-one, a5-one: the soft step and a5-stack without their lanes, one manifold at a time.
const std::vector<Case>& allCases() {
  static const std::vector<Case> list = {
      {"a2", "a2 (m=10)", "a2:m=10", true},
      {"a2-m4", "a2 (m=4)", "a2:m=4", true},
      {"a3", "a3 (n=4 m=1)", "a3:n=4:m=1", true},
      {"a4", "a4 (n=4 m=1)", "a4:n=4:m=1", true},
      {"a5", "a5 (n=4 m=1)", "a5:n=4:m=1", true},
      {"a5-stack", "a5 pyramid.json", "a5:n=4:m=1:kappa=0.85:tau=0:warm=on:cblock=on", true},
      {"a5-one", "a5 one by one", "a5:n=4:m=1:kappa=0.85:tau=0:warm=on:cblock=on:lanes=off", false},  // a5-stack without lanes
      {"soft", "soft (n=4)", "soft:n=4:m=1", true},
      {"soft-colours", "soft colours", "soft:n=4:m=1:colours=on", false},
      {"soft-one", "soft one by one", "soft:n=4:m=1:lanes=off", false},  // what the lanes buy: the same numbers
      {"bullet", "bullet (10 it)", "bullet:it=10", true},
      {"ode", "ode (quick, 20 it)", "ode:it=20", true},
      {"mujoco", "mujoco (newton)", "mujoco:it=100", true},
  };
  return list;
}

// --- one run ----------------------------------------------------------------------------------

struct Run {
  StageTimes stages;        // mean per step [s]
  double total = 0;         // mean wall time of one step() call [s]
  double worst = 0;         // slowest single step [s]
  int stepsDone = 0;
  bool finite = true;       // false: it diverged
  bool refused = false;     // a peer gave up mid-run (MuJoCo's contact buffers full): no time to compare
  std::string problem;      // then: what the World said diverged, or why the peer gave up
  int contacts = 0;         // contact points at the last step
  double moved = 0;         // largest displacement of a dynamic body from its start [m]
  int movedBody = -1;       // which body
  Vec3 movedBy = Vec3::Zero();  // its displacement [m]
  double moved1s = NAN;     // largest displacement after 1 s of simulated time (NaN: shorter run) [m]
  double maxSpeed = 0;      // fastest dynamic body's linear speed at the end [m/s]
  double jointError = 0;    // largest anchor separation of any joint at the end [m]
  double limitExcess = 0;   // largest angle beyond a joint limit (hinge, swing, twist) at the end [rad]
  double hingeExcess = 0, swingExcess = 0, twistExcess = 0;  // the same per kind of limit [rad]
  int solverIterations = 0, rows = 0;  // substep only: the last step's solver statistics
  uint64_t endHash = 0;     // the state's hash at the end (physics/state_hash.h)
};

// What the run's end state looks like, by our definitions for both engines: displacement, the
// fastest body, joint anchor separation and limit excess (physics/constraints/joints.h).
void measureEnd(Run& r, const Scene& scene, const State& s) {
  const Displacement d = largestDisplacement(scene.model, scene.initial, s);
  r.moved = d.metres;
  r.movedBody = d.body;
  r.movedBy = d.by;
  const Model& model = scene.model;
  for (size_t i = 0; i < model.bodies.size(); ++i)
    if (!model.bodies[i].isStatic) r.maxSpeed = std::max(r.maxSpeed, s.bodies[i].v.norm());
  for (const Joint& j : model.joints) {
    const Pose A = s.bodies[static_cast<size_t>(j.bodyA)].pose(), B = s.bodies[static_cast<size_t>(j.bodyB)].pose();
    r.jointError = std::max(r.jointError, jointError(j, A, B));
    const LimitExcess e = jointLimitExcess(j, A, B);
    r.hingeExcess = std::max(r.hingeExcess, e.hinge);
    r.swingExcess = std::max(r.swingExcess, e.swing);
    r.twistExcess = std::max(r.twistExcess, e.twist);
  }
  r.limitExcess = std::max({r.hingeExcess, r.swingExcess, r.twistExcess});
}

// Each step's wall time, and the largest displacement once 1 s of simulated time has passed
// (measured between timed steps).
class StepTimes final : public RunObserver {
 public:
  StepTimes(const Scene& scene, double dt, std::vector<double>& times)
      : scene_(scene), oneSecond_(std::lround(1.0 / dt)), times_(times) {}
  void observe(const Engine& e, const StepRecord& r) override {
    times_[static_cast<size_t>(r.step - 1)] = r.seconds;
    if (r.step == oneSecond_) moved1s = largestDisplacement(scene_.model, scene_.initial, e.state()).metres;
  }
  double moved1s = NAN;

 private:
  const Scene& scene_;
  long long oneSecond_;
  std::vector<double>& times_;
};

// One timed run of a case: a fresh World (or Bullet world) built outside the timed steps.
Run runCase(const Scene& scene, const Case& c, const SolverSettings& settings, int steps, std::vector<double>& stepTimes) {
  std::unique_ptr<World> world;
  std::unique_ptr<Engine> engine;
  if (c.engine() == EngineKind::Peer) {
    engine = lab::makePeerEngine(lab::peerSettings(lab::parseMethods(c.spec).at(0), settings), scene.model, scene.initial);
  } else {
    world = std::make_unique<World>(scene.model, settings, scene.initial);
    engine = std::make_unique<WorldEngine>(*world);
  }
  StepTimes times(scene, settings.dt, stepTimes);
  RunDriver run(*engine, steps);
  run.add(times);
  const RunOutcome& o = run.run();
  Run r;
  r.stepsDone = static_cast<int>(o.steps);
  // A peer that gives up mid-run (MuJoCo's contact buffers full) is no time to compare: said with
  // its reason, never a figure; what a peer cannot model is no failure of the bench.
  r.finite = o.end != RunOutcome::End::Diverged;
  r.refused = o.end == RunOutcome::End::Refused;
  r.problem = r.refused ? "refused: " + o.message : o.message;
  r.moved1s = times.moved1s;
  const double n = std::max(1, r.stepsDone);
  for (int k = 0; k < r.stepsDone; ++k) {
    r.total += stepTimes[static_cast<size_t>(k)];
    r.worst = std::max(r.worst, stepTimes[static_cast<size_t>(k)]);
  }
  r.total /= n;
  if (world) {
    const StageTimes& t = world->totalTimes();
    r.stages = StageTimes{t.s1 / n, t.s2 / n, t.s3 / n, t.s4 / n};
    r.contacts = world->lastReport().contactPoints;
    r.solverIterations = world->lastReport().solver.iterations;
    r.rows = world->lastReport().solver.rows;
  } else if (c.peer() == kBulletPeer) {
    r.contacts = static_cast<const lab::BulletEngine&>(*engine).peer().contactPoints();
  } else {  // ODE and MuJoCo keep no contacts between steps: the points penetrating at the end
    r.contacts = engine->depths().points;
  }
  measureEnd(r, scene, engine->state());
  r.endHash = stateHash(engine->state());
  return r;
}

// --- results ----------------------------------------------------------------------------------

struct Result {
  std::string scene;
  size_t sceneIndex = 0;
  const Case* c = nullptr;
  SolverSettings settings;   // substep cases
  std::vector<Run> runs;     // one per repeat
  Run median;
  const Model* model = nullptr;
  bool repeatable = true;    // contacts, displacement, speed and joint errors the same in every repeat
  double ratio = NAN;        // median total / Bullet's median total on the same scene
  int threads = 1;           // substep cases: the threads a step ran on (--threads runs each case twice)
  // --core-check, on a case's N-thread result: the cores timed, and per core its one-thread runs
  // pinned there (one a repeat) and their median step time [s].
  std::vector<int> cores;
  std::vector<std::vector<Run>> alone;
  std::vector<double> aloneMedian;
  std::vector<double> roundTrip;  // per repeat, before the N-thread run: cores[0] to cores[1] and back [ns]
  std::string label() const { return threads == 1 ? c->label : std::string(c->label) + " x" + std::to_string(threads); }
};

Run medianRun(std::vector<Run> runs) {
  std::sort(runs.begin(), runs.end(), [](const Run& a, const Run& b) { return a.total < b.total; });
  const size_t n = runs.size();
  if (n % 2 == 1) return runs[n / 2];
  Run a = runs[n / 2 - 1];
  const Run& b = runs[n / 2];
  a.stages = StageTimes{(a.stages.s1 + b.stages.s1) / 2, (a.stages.s2 + b.stages.s2) / 2,
                        (a.stages.s3 + b.stages.s3) / 2, (a.stages.s4 + b.stages.s4) / 2};
  a.total = (a.total + b.total) / 2;
  a.worst = (a.worst + b.worst) / 2;
  return a;  // contacts and displacement: the same in every repeat when `repeatable`
}

// Totals of the runs, in repeat order [s].
std::vector<double> totals(const Result& r) {
  std::vector<double> t;
  for (const Run& run : r.runs) t.push_back(run.total);
  return t;
}

// (slowest - fastest) / median of a case's repeats: how noisy its figure is.
double spread(const Result& r) {
  const std::vector<double> t = totals(r);
  if (t.size() < 2 || !(r.median.total > 0)) return 0;
  const auto [lo, hi] = std::minmax_element(t.begin(), t.end());
  return (*hi - *lo) / r.median.total;
}

// One case against another on the same scene: the ratio of the median totals, and the range of
// the ratios of the repeats taken pairwise (repeat k of both ran close together in time, so the
// range shows how much the machine's noise moves the ratio).
Ratio ratio(const Result* a, const Result* b) {
  Ratio q;
  if (!a || !b || !(b->median.total > 0)) return q;
  q.median = a->median.total / b->median.total;
  for (size_t k = 0; k < a->runs.size() && k < b->runs.size(); ++k) {
    const double x = a->runs[k].total / b->runs[k].total;
    q.lo = std::isnan(q.lo) ? x : std::min(q.lo, x);
    q.hi = std::isnan(q.hi) ? x : std::max(q.hi, x);
  }
  return q;
}

const Result* find(const std::vector<Result>& results, const std::string& scene, const char* caseId, int threads = 1) {
  for (const Result& r : results)
    if (r.scene == scene && std::string(r.c->id) == caseId && r.threads == threads) return &r;
  return nullptr;
}

// The comparisons the issue asks for, per scene: A5 against A3 (what A5's refactoring saves), A5
// against A2 at equal solver work (4 sweeps per step), A5 against Bullet; and the goal (A5 at
// n = 4, m = 1 on the pyramid at most half of Bullet's step).
struct Comparison {
  std::string scene;
  const Result *a5 = nullptr, *a3 = nullptr, *a4 = nullptr, *a2m4 = nullptr, *bullet = nullptr;
  Ratio a5a3, a5a4, a5a2m4, a5bullet;
  double s3a5a3 = NAN;  // ratio of the velocity stage alone (s3), where the algorithms differ
  // The goal is judged on the pyramid standing: a5-stack when it ran (at Havok's defaults, a5,
  // the pyramid falls apart, and a heap of falling boxes is other work than Bullet's pyramid).
  const Result* goal = nullptr;
  Ratio goalBullet;
};
constexpr double kGoalVsBullet = 0.5;
constexpr double kDegreesPerRadian = 180 / 3.14159265358979323846;
constexpr const char* kGoalScene = "pyramid";

std::vector<Comparison> compare(const std::vector<Result>& results) {
  std::vector<Comparison> list;
  for (const Result& r : results) {
    if (std::any_of(list.begin(), list.end(), [&](const Comparison& c) { return c.scene == r.scene; })) continue;
    Comparison c;
    c.scene = r.scene;
    c.a5 = find(results, r.scene, "a5");
    c.a3 = find(results, r.scene, "a3");
    c.a4 = find(results, r.scene, "a4");
    c.a2m4 = find(results, r.scene, "a2-m4");
    c.bullet = find(results, r.scene, "bullet");
    if (!c.a5) continue;
    c.a5a3 = ratio(c.a5, c.a3);
    c.a5a4 = ratio(c.a5, c.a4);
    c.a5a2m4 = ratio(c.a5, c.a2m4);
    c.a5bullet = ratio(c.a5, c.bullet);
    if (c.a3 && c.a3->median.stages.s3 > 0) c.s3a5a3 = c.a5->median.stages.s3 / c.a3->median.stages.s3;
    c.goal = find(results, r.scene, "a5-stack");
    if (!c.goal) c.goal = c.a5;
    c.goalBullet = ratio(c.goal, c.bullet);
    list.push_back(c);
  }
  return list;
}

void printTimeTable(const std::vector<Result>& results, std::ostream& out) {
  char line[512];
  out << "Time per step (median run of the repeats; spread = (slowest - fastest) / median of the repeats):\n";
  std::snprintf(line, sizeof line, "%-12s %-15s %7s %7s %7s %7s %9s %7s %9s\n", "scene", "algo", "s1", "s2", "s3",
                "s4", "total", "spread", "vs Bullet");
  out << line;
  std::snprintf(line, sizeof line, "%-12s %-15s %7s %7s %7s %7s %9s %7s %9s\n", "", "", "ms", "ms", "ms", "ms",
                "ms/step", "%", "");
  out << line;
  for (const Result& r : results) {
    const Run& m = r.median;
    const bool ours = r.c->engine() == EngineKind::Substep;
    auto stage = [&](double s) { return ours ? fmt("%7.3f", s * 1e3) : std::string("      -"); };
    const std::string vs = std::isnan(r.ratio) ? "-" : fmt("%.2fx", r.ratio);
    const std::string total = m.refused ? "refused" : fmt("%.3f", m.total * 1e3);
    std::snprintf(line, sizeof line, "%-12s %-15s %s %s %s %s %9s %7.1f %9s\n", r.scene.c_str(), r.label().c_str(),
                  stage(m.stages.s1).c_str(), stage(m.stages.s2).c_str(), stage(m.stages.s3).c_str(),
                  stage(m.stages.s4).c_str(), total.c_str(), 100 * spread(r), vs.c_str());
    out << line;
  }
}

void printEndTable(const std::vector<Result>& results, int steps, std::ostream& out) {
  char line[512];
  out << "\nWhat it bought, at the end of the run (" << steps << " steps) unless said:\n";
  std::snprintf(line, sizeof line, "%-12s %-15s %8s %9s %9s %8s %8s %8s  %s\n", "scene", "algo", "contacts",
                "moved 1s", "moved", "max v", "joint", "limit", "moved most");
  out << line;
  std::snprintf(line, sizeof line, "%-12s %-15s %8s %9s %9s %8s %8s %8s\n", "", "", "", "m", "m", "m/s", "err mm",
                "over deg");
  out << line;
  for (const Result& r : results) {
    const Run& m = r.median;
    const Model* model = r.model;
    std::string moved = fmt("%.4f", m.moved);
    if (!m.finite) moved = "NaN@" + std::to_string(m.stepsDone);
    if (m.refused) moved = "refused@" + std::to_string(m.stepsDone);
    const std::string moved1s = std::isnan(m.moved1s) ? "-" : fmt("%.4f", m.moved1s);
    const bool joints = !model->joints.empty();
    const std::string err = joints ? fmt("%.2f", m.jointError * 1e3) : "-";
    const std::string over = joints ? fmt("%.1f", m.limitExcess * kDegreesPerRadian) : "-";
    const std::string who = m.movedBody >= 0 ? model->bodies[static_cast<size_t>(m.movedBody)].name : "-";
    std::snprintf(line, sizeof line, "%-12s %-15s %8d %9s %9s %8.3f %8s %8s  %s%s\n", r.scene.c_str(), r.label().c_str(),
                  m.contacts, moved1s.c_str(), moved.c_str(), m.maxSpeed, err.c_str(), over.c_str(), who.c_str(),
                  r.repeatable ? "" : "  (differs between repeats)");
    out << line;
  }
}

void printComparisons(const std::vector<Comparison>& comps, std::ostream& out) {
  char line[512];
  out << "\nA5 (n=4 m=1) against A3 and A4 (same n, m), A2 at equal solver work (m=4) and Bullet: ratio of the\n"
         "median totals (in brackets the range of the repeats' pairwise ratios); saving = 1 - a5/a3:\n";
  std::snprintf(line, sizeof line, "%-12s %9s %20s %7s %8s %20s %20s %20s\n", "scene", "a5 ms", "a5/a3", "saving",
                "s3 a5/a3", "a5/a4", "a5/a2-m4", "a5/bullet");
  out << line;
  for (const Comparison& c : comps) {
    const std::string saving = c.a5a3.valid() ? fmt("%.0f%%", 100 * (1 - c.a5a3.median)) : "-";
    const std::string s3 = std::isnan(c.s3a5a3) ? "-" : fmt("%.2fx", c.s3a5a3);
    std::snprintf(line, sizeof line, "%-12s %9.3f %20s %7s %8s %20s %20s %20s\n", c.scene.c_str(),
                  c.a5->median.total * 1e3, ratioText(c.a5a3).c_str(), saving.c_str(), s3.c_str(),
                  ratioText(c.a5a4).c_str(), ratioText(c.a5a2m4).c_str(), ratioText(c.a5bullet).c_str());
    out << line;
  }
}

void printGoal(const std::vector<Comparison>& comps, std::ostream& out) {
  for (const Comparison& c : comps) {
    if (c.scene != kGoalScene || !c.goalBullet.valid()) continue;
    const bool met = c.goalBullet.median <= kGoalVsBullet;
    const double needed = kGoalVsBullet * c.bullet->median.total;
    out << "\nGoal: A5 (n=4, m=1) on the " << kGoalScene << " at most " << fmt("%.2fx", kGoalVsBullet)
        << " Bullet's step time, judged on " << c.goal->c->label << ": " << (met ? "MET" : "NOT MET") << " ("
        << ratioText(c.goalBullet) << ", " << fmt("%.3f", c.goal->median.total * 1e3) << " ms against Bullet's "
        << fmt("%.3f", c.bullet->median.total * 1e3) << " ms";
    if (!met)
      out << "; the goal needs <= " << fmt("%.3f", needed * 1e3) << " ms, "
          << fmt("%.1fx", c.goal->median.total / needed) << " faster than now";
    out << ")\n";
  }
}

// --core-check on an N-thread result: the speed-up over the (unpinned) one-thread run that the
// cores' own speeds allow at best, and how much of that best the N threads reached.
struct CoreAllowance {
  double bound = NAN;       // the shortest N-thread step the cores allow [s] (coreBound)
  double speedUp = NAN;     // one thread's median step over that bound
  double efficiency = NAN;  // that bound over the N threads' median step
  bool valid() const { return !std::isnan(bound); }
};

CoreAllowance coreAllowance(const Result& threaded, const Result& one) {
  CoreAllowance a;
  a.bound = coreBound(threaded.aloneMedian, threaded.threads);
  if (!a.valid()) return a;
  a.speedUp = one.median.total / a.bound;
  a.efficiency = a.bound / threaded.median.total;
  return a;
}

// --core-check: how long the first two cores took to hand a cache line over, median and range of
// the repeats; "" without the figure.
std::string roundTripText(const Result& r) {
  std::vector<double> t;
  for (double x : r.roundTrip)
    if (std::isfinite(x)) t.push_back(x);
  if (t.empty() || r.cores.size() < 2) return "";
  std::string out = "a cache line from core " + std::to_string(r.cores[0]) + " to core " + std::to_string(r.cores[1]) +
                    " and back in " + fmt("%.0f", app::median(t)) + " ns";
  const auto [low, high] = std::minmax_element(t.begin(), t.end());
  if (t.size() > 1) out += " (" + fmt("%.0f", *low) + "-" + fmt("%.0f", *high) + ")";
  return out;
}

// --threads N: each substep case on N threads against itself on one, run for run, and whether
// the two ended in the same state to the last bit (the end states' hashes).
void printThreads(const std::vector<Result>& results, std::ostream& out) {
  bool header = false;
  for (const Result& r : results) {
    if (r.threads == 1) continue;
    const Result* one = find(results, r.scene, r.c->id, 1);
    if (!one) continue;
    if (!header) {
      out << "\nThreads (speed-up: one thread's step time over " << r.threads
          << " threads', median and range of the repeats taken pairwise; hashes of the end states):\n";
      char line[256];
      std::snprintf(line, sizeof line, "%-12s %-15s %9s %9s %20s %17s %17s %s\n", "scene", "algo", "1 thread", "threads",
                    "speed-up", "hash, 1 thread", "hash, threads", "same");
      out << line;
      header = true;
    }
    const Ratio q = ratio(one, &r);
    char line[256];
    std::snprintf(line, sizeof line, "%-12s %-15s %9.3f %9.3f %20s %17s %17s %s\n", r.scene.c_str(), r.c->label,
                  one->median.total * 1e3, r.median.total * 1e3, ratioText(q).c_str(), hashText(one->median.endHash).c_str(),
                  hashText(r.median.endHash).c_str(), one->median.endHash == r.median.endHash ? "yes" : "NO");
    out << line;
    const CoreAllowance a = coreAllowance(r, *one);
    if (!a.valid()) continue;
    out << "    one thread pinned to each core:";
    for (size_t k = 0; k < r.cores.size(); ++k)
      out << (k ? "," : "") << " core " << r.cores[k] << " " << fmt("%.3f", r.aloneMedian[k] * 1e3) << " ms";
    out << "; " << r.threads << " threads could take " << fmt("%.3f", a.bound * 1e3) << " ms at best, a speed-up of at most "
        << fmt("%.2fx", a.speedUp) << "; reached " << fmt("%.0f", 100 * a.efficiency) << " % of that";
    const std::string handOver = roundTripText(r);
    if (!handOver.empty()) out << "; " << handOver;
    out << "\n";
  }
  if (header && std::any_of(results.begin(), results.end(), [](const Result& r) { return !r.cores.empty(); }))
    out << "  (at best: each core working in proportion to its own speed, nothing serial, nothing lost to sharing;\n"
           "  the hand-over, timed before each run, is some 100 ns on cores that share a cache and several times that\n"
           "  across dies, where work handed between threads unit by unit gains little: docs/benchmarks.md)\n";
}

// Issue 20's targets, where their cases and scenes ran: the soft step and A5 (pyramid.json's
// settings) against Bullet on one thread, and the speed-up on --threads.
struct Target {
  const char* scene;
  const char* caseId;
  bool speedUp;  // false: our step time over Bullet's at most `bound`; true: one thread's over N threads' at least `bound`
  double bound;
};
constexpr Target kTargets[] = {
    {"pyramid", "soft", false, 0.40},     {"pyramid_40", "soft", false, 0.40},     {"pyramid_100", "soft", false, 0.40},
    {"pyramid", "a5-stack", false, 0.35}, {"pyramid_40", "a5-stack", false, 0.35}, {"pyramid_100", "soft", true, 1.6},
    {"pile_10000", "soft", true, 1.6},    {"pyramid_100", "soft-colours", true, 1.6}, {"pile_10000", "soft-colours", true, 1.6},
    {"pyramid_100", "a5-stack", true, 1.6},  {"pile_10000", "a5-stack", true, 1.6},
};

struct TargetResult {
  const Target* target;
  const Result* one;    // the case on one thread
  const Result* other;  // Bullet on the scene, or the case on N threads
  Ratio ratio;          // one's step time over other's
  bool met;
};

std::vector<TargetResult> judgeTargets(const std::vector<Result>& results) {
  std::vector<TargetResult> out;
  for (const Target& t : kTargets) {
    const Result* one = find(results, t.scene, t.caseId, 1);
    if (!one) continue;
    const Result* other = nullptr;
    for (const Result& r : results)
      if (r.scene == t.scene && (t.speedUp ? std::string(r.c->id) == t.caseId && r.threads > 1 : r.c->peer() == kBulletPeer))
        other = &r;
    if (!other || !one->median.finite || !other->median.finite) continue;
    const Ratio q = ratio(one, other);
    out.push_back({&t, one, other, q, t.speedUp ? q.median >= t.bound : q.median <= t.bound});
  }
  return out;
}

void printTargets(const std::vector<Result>& results, std::ostream& out) {
  const std::vector<TargetResult> judged = judgeTargets(results);
  if (!judged.empty()) out << "\nTargets:\n";
  for (const TargetResult& j : judged) {
    const Target& t = *j.target;
    out << "  " << t.scene << " " << j.one->c->label;
    if (t.speedUp) out << " on " << j.other->threads << " threads: speed-up at least " << fmt("%.2fx", t.bound);
    else out << ": at most " << fmt("%.2fx", t.bound) << " Bullet's step time";
    out << ": " << (j.met ? "MET" : "NOT MET") << " (" << ratioText(j.ratio, t.bound) << ")";
    const CoreAllowance a = t.speedUp ? coreAllowance(*j.other, *j.one) : CoreAllowance{};
    if (a.valid()) out << "; the cores allowed at most " << fmt("%.2fx", a.speedUp);
    const std::string handOver = t.speedUp ? roundTripText(*j.other) : "";
    if (!handOver.empty()) out << "; " << handOver;
    out << "\n";
  }
}

void printTables(const std::vector<Result>& results, int steps, std::ostream& out) {
  printTimeTable(results, out);
  printEndTable(results, steps, out);
  printThreads(results, out);
  const std::vector<Comparison> comps = compare(results);
  if (!comps.empty()) {
    printComparisons(comps, out);
    printGoal(comps, out);
  }
  printTargets(results, out);
}

nlohmann::json ratioJson(const Ratio& q) {
  if (!q.valid()) return nullptr;
  return {{"median", q.median}, {"repeats_min", q.lo}, {"repeats_max", q.hi}};
}

nlohmann::json runJson(const Run& r, const Model& model) {
  auto number = [](double x) { return std::isnan(x) ? nlohmann::json(nullptr) : nlohmann::json(x); };
  nlohmann::json j = {{"ms_per_step", {{"s1", r.stages.s1 * 1e3}, {"s2", r.stages.s2 * 1e3}, {"s3", r.stages.s3 * 1e3},
                           {"s4", r.stages.s4 * 1e3}, {"total", r.total * 1e3}}},
          {"worst_step_ms", r.worst * 1e3},
          {"steps_done", r.stepsDone},
          {"finite", r.finite},
          {"refused", r.refused},
          {"problem", r.problem},
          {"contact_points", r.contacts},
          {"moved_1s_m", number(r.moved1s)},
          {"moved_m", r.moved},
          {"max_speed_mps", r.maxSpeed},
          {"joint_error_m", r.jointError},
          {"limit_excess_rad", {{"any", r.limitExcess}, {"hinge", r.hingeExcess}, {"swing", r.swingExcess},
                                {"twist", r.twistExcess}}}};
  if (r.movedBody >= 0) {
    j["moved_body"] = model.bodies[static_cast<size_t>(r.movedBody)].name;
    j["moved_by_m"] = {r.movedBy.x(), r.movedBy.y(), r.movedBy.z()};
  }
  return j;
}

// Checked before anything runs, so a bad --json fails at once, not after minutes of timing.
void checkJsonPath(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw UsageError("--json " + path + ": folder " + dir.string() + " does not exist");
  if (access(dir.c_str(), W_OK) != 0) throw UsageError("--json " + path + ": cannot write in " + dir.string());
  if (fs::is_directory(target, ec)) throw UsageError("--json " + path + ": is a folder; give a file name");
}

// Written under a temporary name in the same folder, then renamed over `path`.
void writeJson(const std::string& path, const nlohmann::json& doc) {
  app::AtomicFile file(path);
  file.out() << doc.dump(2) << "\n";
  file.commit();
}

// --- scaling mode -----------------------------------------------------------------------------
//
// substep-bench --scaling: piles of 100, 300, 1000, 3000 and 10 000 unit boxes (columns of ten
// with 0.1 m gaps, the columns 1.1 m apart on a square grid, as pile.json lays out its 1000),
// each case stepped --steps times on a fresh world, and the log-log slope of the step time
// against the body count (least squares over the sizes; 1 is linear). Each run is a child
// process, so that its peak resident memory (getrusage of the child) is its own; memory per body
// is the 10 000-box peak over the 100-box one, divided by the 9 900 bodies between them.

std::string pileSceneText(int boxes) {
  const int columns = (boxes + 9) / 10;
  const int side = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(columns))));
  const double spacing = 1.1, half = 0.5 * spacing * (side - 1);
  nlohmann::json gens = nlohmann::json::array();
  for (int c = 0; c < columns; ++c) {
    const int count = std::min(10, boxes - 10 * c);
    gens.push_back({{"type", "stack"},
                    {"name", "col_" + std::to_string(c)},
                    {"count", count},
                    {"half_extents", {0.5, 0.5, 0.5}},
                    {"position", {-half + spacing * (c % side), 0.1, -half + spacing * (c / side)}},
                    {"gap", 0.1},
                    {"mass", 1},
                    {"friction", 0.6}});
  }
  const double ground = half + 5;
  const nlohmann::json scene = {
      {"description", "scaling pile of " + std::to_string(boxes) + " boxes"},
      {"solver", {{"dt", 1.0 / 60.0}}},
      {"bodies",
       {{{"name", "ground"}, {"static", true}, {"shape", {{"type", "box"}, {"half_extents", {ground, 0.5, ground}}}},
         {"position", {0, -0.5, 0}}, {"friction", 0.6}}}},
      {"generators", gens}};
  return scene.dump();
}

struct ScalingRun {
  double step = 0;      // mean wall time of a step [s]
  int contacts = 0;     // contact points at the last step
  bool finite = true;
  long peakKiB = 0;     // the child's peak resident memory [KiB]
};

// One run in a child process: the pile built, stepped `steps` times, each step timed.
ScalingRun scalingRunInChild(const Case& c, int boxes, int steps) {
  int fd[2];
  if (pipe(fd) != 0) throw std::runtime_error("pipe failed");
  std::cout.flush();
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {  // the child: never returns into the parent's code, whatever happens
    close(fd[0]);
    try {
      SceneLimits lim;
      lim.maxBodies = boxes + 1;
      const Scene scene = parseScene(pileSceneText(boxes), "pile", ".", lim);
      std::vector<double> times(static_cast<size_t>(steps));
      Run r = runCase(scene, c, c.settings(1.0 / 60.0), steps, times);
      const double out[3] = {r.total, static_cast<double>(r.contacts), r.finite && !r.refused ? 1.0 : 0.0};
      const ssize_t w = write(fd[1], out, sizeof out);
      _exit(w == static_cast<ssize_t>(sizeof out) ? 0 : 1);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "substep-bench: %s run of %d boxes: %s\n", c.id, boxes, e.what());
    }
    _exit(1);
  }
  close(fd[1]);
  double in[3] = {0, 0, 0};
  const ssize_t got = read(fd[0], in, sizeof in);
  close(fd[0]);
  int status = 0;
  struct rusage usage {};
  wait4(pid, &status, 0, &usage);
  if (got != static_cast<ssize_t>(sizeof in) || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw std::runtime_error(std::string("the ") + c.id + " run of " + std::to_string(boxes) + " boxes failed");
  return ScalingRun{in[0], static_cast<int>(in[1]), in[2] != 0, usage.ru_maxrss};
}

constexpr double kScalingGoal = 1.1;

// A pile size's figure: the run with the median step time, and the largest peak memory of any run.
struct ScalingPoint {
  ScalingRun median;
  long peakKiB = 0;
};

ScalingPoint scalingPoint(const Case& c, int boxes, int steps, int repeat) {
  std::vector<ScalingRun> runs;
  for (int k = 0; k < repeat; ++k) runs.push_back(scalingRunInChild(c, boxes, steps));
  std::sort(runs.begin(), runs.end(), [](const ScalingRun& a, const ScalingRun& b) { return a.step < b.step; });
  ScalingPoint p{runs[runs.size() / 2]};
  for (const ScalingRun& r : runs) p.peakKiB = std::max(p.peakKiB, r.peakKiB);
  return p;
}

// A case over the pile sizes: a row each, then the slope and the memory per box; returns its JSON.
nlohmann::json scalingCase(const Case& c, const std::vector<int>& sizes, int steps, int repeat, bool& allFinite) {
  std::vector<std::pair<double, double>> timeByBoxes;  // (boxes, step time)
  std::vector<long> peaks;
  nlohmann::json rows = nlohmann::json::array();
  for (int boxes : sizes) {
    const ScalingPoint p = scalingPoint(c, boxes, steps, repeat);
    const ScalingRun& m = p.median;
    allFinite = allFinite && m.finite;
    timeByBoxes.emplace_back(boxes, m.step);
    peaks.push_back(p.peakKiB);
    std::printf("%-16s %7d %11.3f %9d %10.1f %12.2f%s\n", c.label, boxes, m.step * 1e3, m.contacts, p.peakKiB / 1024.0,
                m.step / boxes * 1e6, m.finite ? "" : "  NOT FINITE");
    std::fflush(stdout);
    rows.push_back({{"boxes", boxes}, {"step_ms", m.step * 1e3}, {"contact_points", m.contacts},
                    {"peak_rss_kib", p.peakKiB}, {"finite", m.finite}});
  }
  const double slope = lab::logSlope(timeByBoxes);  // NaN for fewer than two sizes
  nlohmann::json entry = {{"case", c.id}, {"label", c.label}, {"sizes", rows}, {"slope", slope}};
  std::printf("%-16s slope of log step time against log boxes: %.3f (goal at most %.1f: %s)\n", c.label, slope,
              kScalingGoal, slope <= kScalingGoal ? "MET" : "NOT MET");
  if (timeByBoxes.size() > 1) {
    const double first = timeByBoxes.front().first, last = timeByBoxes.back().first;
    const double perBody = (peaks.back() - peaks.front()) * 1024.0 / (last - first);
    std::printf("%-16s peak resident memory %.1f MiB at %d boxes; %.2f KiB a box (from %d to %d boxes)\n", c.label,
                peaks.back() / 1024.0, static_cast<int>(last), perBody / 1024.0, static_cast<int>(first),
                static_cast<int>(last));
    entry["bytes_per_box"] = perBody;
  }
  std::printf("\n");
  return entry;
}

int scaling(const std::vector<const Case*>& cases, const std::vector<int>& sizes, int steps, int repeat,
            const std::string& json) {
  if (!json.empty()) checkJsonPath(json);
  std::cout << "substep-bench --scaling  " << utcNow() << "  " << cpuModel() << "; build " << SUBSTEP_BUILD_TYPE
            << "; load average " << loadAverage() << "\n"
            << "piles of unit boxes in columns of ten; " << steps << " steps of 1/60 s, every step timed; median of "
            << repeat << " runs, each a fresh child process\n\n";
  std::printf("%-16s %7s %11s %9s %10s %12s\n", "case", "boxes", "step [ms]", "contacts", "peak [MiB]", "per box [us]");
  nlohmann::json list = nlohmann::json::array();
  bool allFinite = true;
  for (const Case* c : cases) list.push_back(scalingCase(*c, sizes, steps, repeat, allFinite));
  if (!json.empty()) {
    nlohmann::json doc = {{"tool", "substep-bench --scaling"}, {"date_utc", utcNow()}, {"cpu", cpuModel()},
                          {"build_type", SUBSTEP_BUILD_TYPE}, {"source", sourceState()}, {"steps", steps},
                          {"repeat", repeat}, {"goal_slope_at_most", kScalingGoal}, {"cases", list}};
    writeJson(json, doc);
    std::cout << "wrote " << json << "\n";
  }
  return allFinite ? 0 : kExitNonFinite;
}

// --- the options ------------------------------------------------------------------------------

struct Options {
  int steps = 300;
  int repeat = 5;
  std::vector<std::string> scenes{"pyramid", "chain", "ragdoll_pile"};
  std::vector<std::string> algos;
  std::string json;
  bool quick = false;
  bool scaling = false;
  int threads = 1;      // > 1: every substep case also on this many threads
  bool coreCheck = false;  // with threads > 1: each N-thread case also on one thread pinned to each core
  std::vector<int> sizes{100, 300, 1000, 3000, 10000};
  std::string command;  // the command line, for the JSON
};

// --- planning ---------------------------------------------------------------------------------

const Case& knownCase(const std::string& id) {
  const auto it = std::find_if(allCases().begin(), allCases().end(), [&](const Case& c) { return id == c.id; });
  if (it == allCases().end()) {
    std::string known;
    for (const Case& c : allCases()) known += std::string(known.empty() ? "" : ", ") + c.id;
    throw UsageError("--algos: unknown case \"" + id + "\"; known: " + known);
  }
  return *it;
}

// --algos in the order given, each once; else the default cases (a5-stack and bullet for --scaling).
std::vector<const Case*> chooseCases(const std::vector<std::string>& algos, bool scaling) {
  std::vector<const Case*> cases;
  if (algos.empty()) {
    for (const Case& c : allCases())
      if (scaling ? std::string(c.id) == "a5-stack" || std::string(c.id) == "bullet" : c.byDefault) cases.push_back(&c);
    return cases;
  }
  for (const std::string& id : algos) {
    const Case* c = &knownCase(id);
    if (std::find(cases.begin(), cases.end(), c) == cases.end()) cases.push_back(c);
  }
  return cases;
}

struct BenchPlan {
  std::vector<Scene> scenes;
  std::vector<Result> results;       // a scene's cases together, in table order
  std::vector<std::string> skipped;  // scenes without a Bullet peer, and why
};

// A case on a scene, checked before anything is timed: its World can be built, or Bullet has a
// peer for the scene (else it is skipped there, and said so).
std::optional<Result> planCase(const Scene& scene, size_t index, const std::string& name, const Case* c,
                               std::vector<std::string>& skipped) {
  const double dt = scene.solver.get(&SolverSettings::dt).value_or(1.0 / 60.0);
  Result r;
  r.scene = name;
  r.sceneIndex = index;
  r.model = &scene.model;
  r.c = c;
  if (c->engine() == EngineKind::Substep) {
    try {
      r.settings = c->settings(dt);
      World probe(scene.model, r.settings, scene.initial);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("case ") + c->id + " on " + name + ": " + e.what());
    }
    return r;
  }
  const std::string engine = lab::peerDisplayName(c->peer());
  const std::string why = lab::peerUnsupported(c->peer(), scene.model, scene.initial);
  if (!why.empty()) {
    std::cout << "substep-bench: no " << engine << " peer for " << name << ", " << engine << " skipped there: " << why << "\n";
    skipped.push_back(name + " (" + engine + "): " + why);
    return std::nullopt;
  }
  r.settings.dt = dt;
  r.settings.iterations = c->settings(dt).iterations;
  return r;
}

// The cores this process may run on (its affinity mask), the first kMaxCheckedCores of them:
// --core-check times a case on each.
constexpr size_t kMaxCheckedCores = 16;
std::vector<int> allowedCores() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) != 0)
    throw std::runtime_error(std::string("--core-check: cannot read this process's cores: ") + std::strerror(errno));
  std::vector<int> cores;
  for (int c = 0; c < CPU_SETSIZE && cores.size() < kMaxCheckedCores; ++c)
    if (CPU_ISSET(c, &set)) cores.push_back(c);
  return cores;
}

// Runs f() with the calling thread on `core` alone, then gives it back the cores it had. A World
// on one thread steps on its caller, so the whole step runs there.
template <class F>
auto onCore(int core, F f) {
  cpu_set_t before, only;
  CPU_ZERO(&only);
  CPU_SET(core, &only);
  if (sched_getaffinity(0, sizeof before, &before) != 0 || sched_setaffinity(0, sizeof only, &only) != 0)
    throw std::runtime_error("--core-check: cannot pin the benchmark to core " + std::to_string(core) + ": " +
                             std::strerror(errno));
  struct Restore {
    cpu_set_t* mask;
    ~Restore() { sched_setaffinity(0, sizeof *mask, mask); }
  } restore{&before};
  return f();
}

BenchPlan planBench(const std::vector<std::string>& sceneNames, const std::vector<const Case*>& cases, int threads,
                    const std::vector<int>& checkedCores) {
  BenchPlan plan;
  std::vector<std::string> names;
  plan.scenes.reserve(sceneNames.size());  // results point at their scene's model
  for (const std::string& name : sceneNames) {
    const std::string path = app::scenePath(name);
    try {
      plan.scenes.push_back(loadScene(path));
    } catch (const SceneError& e) {
      throw UsageError(std::string("--scenes: ") + e.what());
    }
    names.push_back(std::filesystem::path(path).stem().string());
  }
  for (size_t s = 0; s < plan.scenes.size(); ++s)
    for (const Case* c : cases)
      if (std::optional<Result> r = planCase(plan.scenes[s], s, names[s], c, plan.skipped)) {
        plan.results.push_back(*r);
        if (threads > 1 && c->engine() == EngineKind::Substep) {  // the same case on `threads` threads
          r->threads = r->settings.threads = threads;
          r->cores = checkedCores;
          r->alone.resize(checkedCores.size());
          plan.results.push_back(std::move(*r));
        }
      }
  return plan;
}

// --- timing -----------------------------------------------------------------------------------

// Where and how the timed runs ran, for the notes and the JSON.
struct TimedRuns {
  std::string source, loadBefore, loadAfter;
  double wall = 0;  // [s]
};

// Returns the source state, as git sees the tree now.
std::string printHeader(const Options& opt, const std::vector<Result>& results) {
  std::cout << "substep-bench  " << utcNow() << "  " << cpuModel() << ", " << std::thread::hardware_concurrency()
            << " hardware threads, "
            << (opt.threads > 1 ? "substep cases on 1 and " + std::to_string(opt.threads) + " threads, the rest on one" +
                                      (opt.coreCheck ? " (and on one thread pinned to each core)" : "")
                                : std::string("single-threaded runs"))
            << "; soft step lanes " << lanes::kernel().name << "; build " << SUBSTEP_BUILD_TYPE << "; Bullet "
            << bulletVersion() << ", ODE " << lab::peerVersion(kOdePeer) << ", MuJoCo " << lab::peerVersion(kMujocoPeer)
            << "; load average " << loadAverage() << "\n";
  const std::string source = sourceState();
  std::cout << "source " << source << " (as git sees the tree now; the build may be older)\n";
  std::cout << opt.steps << " steps of dt = " << fmt("%.6g", results.empty() ? 0.0 : results[0].settings.dt)
            << " s each, every step timed (no warm-up excluded); median of " << opt.repeat
            << " repeats, each on a freshly built world\n\n";
  std::cout.flush();
  return source;
}

// Repeat k of every case before repeat k + 1 of any, so that slow drift of the machine spreads over all cases.
void timeRepeats(BenchPlan& plan, int steps, int repeat) {
  std::vector<double> stepTimes(static_cast<size_t>(steps));
  int runsPerRepeat = 0;
  for (const Result& r : plan.results) runsPerRepeat += 1 + static_cast<int>(r.cores.size());
  const int totalRuns = repeat * runsPerRepeat;
  int done = 0;
  const auto timed = [&](const Result& r, const SolverSettings& settings, const std::string& label, int rep) {
    Run run = runCase(plan.scenes[r.sceneIndex], *r.c, settings, steps, stepTimes);
    ++done;
    std::fprintf(stderr, "[%d/%d] %-8s %-15s repeat %d/%d: %.3f ms/step\n", done, totalRuns, r.scene.c_str(),
                 label.c_str(), rep + 1, repeat, run.total * 1e3);
    return run;
  };
  for (int rep = 0; rep < repeat; ++rep) {
    for (Result& r : plan.results) {
      if (r.cores.size() >= 2) r.roundTrip.push_back(cacheLineRoundTrip(r.cores[0], r.cores[1]));
      r.runs.push_back(timed(r, r.settings, r.label(), rep));
      // --core-check: right after the N-thread run, the case on one thread on each core in turn.
      SolverSettings one = r.settings;
      one.threads = 1;
      for (size_t k = 0; k < r.cores.size(); ++k)
        r.alone[k].push_back(
            onCore(r.cores[k], [&] { return timed(r, one, std::string(r.c->label) + " core " + std::to_string(r.cores[k]), rep); }));
    }
  }
}

// --- aggregating ------------------------------------------------------------------------------

// The repeats ended alike, so they timed the same work.
bool sameEnd(const Run& a, const Run& b) {
  return a.contacts == b.contacts && a.moved == b.moved && a.finite == b.finite && a.maxSpeed == b.maxSpeed &&
         a.jointError == b.jointError && a.stepsDone == b.stepsDone && a.endHash == b.endHash;
}

// Each case's median run, whether its repeats ended alike, and its ratio to Bullet on its scene.
// Returns whether every run stayed finite.
bool aggregate(std::vector<Result>& results) {
  bool allFinite = true;
  for (Result& r : results) {
    r.median = medianRun(r.runs);
    for (const Run& run : r.runs) {
      r.repeatable = r.repeatable && sameEnd(run, r.runs[0]);
      allFinite = allFinite && run.finite;
    }
    r.aloneMedian.clear();
    for (const std::vector<Run>& core : r.alone) {
      for (const Run& run : core) r.repeatable = r.repeatable && sameEnd(run, r.runs[0]);  // one thread: the same end
      r.aloneMedian.push_back(medianRun(core).total);
    }
  }
  for (Result& r : results)
    for (const Result& b : results)
      if (b.scene == r.scene && b.c->peer() == kBulletPeer && b.median.total > 0 && r.median.finite && !r.median.refused)
        r.ratio = r.median.total / b.median.total;
  return allFinite;
}

bool allRepeatable(const std::vector<Result>& results) {
  return std::all_of(results.begin(), results.end(), [](const Result& r) { return r.repeatable; });
}

// --- printing ---------------------------------------------------------------------------------

void printNotes(const BenchPlan& plan, const TimedRuns& t) {
  std::cout << "\ns1 geometry, s2 formulation, s3 velocities, s4 coordinates: mean per step of the median run; total:\n"
               "wall time of one step() call (includes bookkeeping outside s1-s4). vs Bullet: total / Bullet's total\n"
               "on the same scene. contacts: contact points at the last step. moved: largest distance of any body's\n"
               "centre from where it started (after 1 s, and at the end; dropped scenes: mostly the fall). max v:\n"
               "fastest body. joint err: largest anchor separation; limit over: largest angle beyond a hinge, swing\n"
               "or twist limit; both by our definitions, for Bullet too.\n";
  for (const std::string& s : plan.skipped) std::cout << "No peer for " << s << "\n";
  std::cout << "Timed runs took " << fmt("%.1f", t.wall) << " s; load average before " << t.loadBefore << ", after "
            << t.loadAfter << ".\n";
}

void printWarnings(const std::vector<Result>& results, bool allFinite) {
  if (!allRepeatable(results)) {
    std::cout << "WARNING: some cases ended differently between repeats (contacts, displacement, speed or joint\n"
                 "error differ), so their repeats did not time the same work:\n";
    for (const Result& r : results)
      if (!r.repeatable) std::cout << "  " << r.scene << " " << r.label() << "\n";
  }
  if (!allFinite) {
    std::cout << "WARNING: some runs diverged (NaN@k: at step k):\n";
    for (const Result& r : results)
      if (!r.median.finite) std::cout << "  " << r.scene << " " << r.label() << ": " << r.median.problem << "\n";
  }
  for (const Result& r : results)
    if (r.median.refused)
      std::cout << "Refused mid-run (refused@k: at step k; a peer's limit, not timed): " << r.scene << " " << r.label() << ": "
                << r.median.problem << "\n";
}

// --- the JSON ---------------------------------------------------------------------------------

nlohmann::json resultJson(const Result& r) {
  nlohmann::json j = runJson(r.median, *r.model);
  j["scene"] = r.scene;
  j["case"] = r.c->id;
  j["label"] = r.label();
  j["threads"] = r.threads;
  j["end_hash"] = hashText(r.median.endHash);
  j["engine"] = r.c->engine() == EngineKind::Substep ? std::string("substep") : r.c->peer();
  j["method"] = r.c->spec;
  if (r.c->engine() == EngineKind::Substep) {
    j["settings"] = settingsJson(r.settings);
    j["solver_last_step"] = {{"iterations", r.median.solverIterations}, {"rows", r.median.rows}};
  } else {
    j["settings"] = lab::peerSettingsJson(lab::peerSettings(lab::parseMethods(r.c->spec).at(0), r.settings));
  }
  j["vs_bullet"] = std::isnan(r.ratio) ? nlohmann::json(nullptr) : nlohmann::json(r.ratio);
  j["spread"] = spread(r);
  j["repeatable"] = r.repeatable;
  if (!r.cores.empty()) {
    nlohmann::json cores = nlohmann::json::array();
    for (size_t k = 0; k < r.cores.size(); ++k) {
      nlohmann::json runs = nlohmann::json::array();
      for (const Run& run : r.alone[k]) runs.push_back(run.total * 1e3);
      cores.push_back({{"core", r.cores[k]}, {"one_thread_ms", r.aloneMedian[k] * 1e3}, {"repeats_ms", runs}});
    }
    nlohmann::json handOver = nlohmann::json::array();
    for (double x : r.roundTrip) handOver.push_back(std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr));
    j["core_check"] = {{"cores", cores}, {"best_ms", coreBound(r.aloneMedian, r.threads) * 1e3}, {"round_trip_ns", handOver}};
  }
  nlohmann::json reps = nlohmann::json::array();
  for (const Run& run : r.runs) reps.push_back(runJson(run, *r.model));
  j["repeats"] = reps;
  return j;
}

nlohmann::json comparisonJson(const Comparison& c) {
  nlohmann::json j = {{"scene", c.scene},
                      {"a5_ms", c.a5->median.total * 1e3},
                      {"a5_over_a3", ratioJson(c.a5a3)},
                      {"a5_over_a4", ratioJson(c.a5a4)},
                      {"a5_over_a2_m4", ratioJson(c.a5a2m4)},
                      {"a5_over_bullet", ratioJson(c.a5bullet)},
                      {"s3_a5_over_a3", std::isnan(c.s3a5a3) ? nlohmann::json(nullptr) : nlohmann::json(c.s3a5a3)}};
  if (c.scene == kGoalScene && c.goalBullet.valid())
    j["goal"] = {{"case", c.goal->c->id},
                 {"a5_over_bullet_at_most", kGoalVsBullet},
                 {"a5_over_bullet", ratioJson(c.goalBullet)},
                 {"met", c.goalBullet.median <= kGoalVsBullet}};
  return j;
}

nlohmann::json benchJson(const Options& opt, const BenchPlan& plan, const TimedRuns& t) {
  nlohmann::json doc;
  doc["tool"] = "substep-bench";
  doc["date_utc"] = utcNow();
  doc["machine"] = {{"cpu", cpuModel()}, {"hardware_threads", std::thread::hardware_concurrency()},
                    {"lanes_kernel", lanes::kernel().name}};
  doc["build_type"] = SUBSTEP_BUILD_TYPE;
  doc["source"] = t.source;
  doc["bullet_version"] = bulletVersion();
  doc["ode_version"] = lab::peerVersion(kOdePeer);
  doc["mujoco_version"] = lab::peerVersion(kMujocoPeer);
  doc["load_average"] = {{"before", t.loadBefore}, {"after", t.loadAfter}};
  doc["timed_wall_s"] = t.wall;
  doc["command"] = opt.command;
  doc["steps"] = opt.steps;
  doc["repeat"] = opt.repeat;
  doc["method"] =
      "every step timed with steady_clock, no warm-up excluded; run = mean over its steps; "
      "reported = median over repeats (run with the median total); fresh world per repeat; repeats interleaved";
  doc["results"] = nlohmann::json::array();
  for (const Result& r : plan.results) doc["results"].push_back(resultJson(r));
  doc["comparisons"] = nlohmann::json::array();
  for (const Comparison& c : compare(plan.results)) doc["comparisons"].push_back(comparisonJson(c));
  doc["bullet_skipped"] = plan.skipped;
  doc["threads"] = opt.threads;
  doc["core_check"] = opt.coreCheck;
  doc["targets"] = nlohmann::json::array();
  for (const TargetResult& j : judgeTargets(plan.results))
    doc["targets"].push_back({{"scene", j.target->scene},
                              {"case", j.target->caseId},
                              {"kind", j.target->speedUp ? "speed_up_at_least" : "vs_bullet_at_most"},
                              {"bound", j.target->bound},
                              {"threads", j.target->speedUp ? j.other->threads : 1},
                              {"ratio", ratioJson(j.ratio)},
                              {"cores_allow_at_most",
                               [&]() -> nlohmann::json {
                                 const CoreAllowance a = j.target->speedUp ? coreAllowance(*j.other, *j.one) : CoreAllowance{};
                                 return a.valid() ? nlohmann::json(a.speedUp) : nlohmann::json(nullptr);
                               }()},
                              {"met", j.met}});
  return doc;
}

// --- main -------------------------------------------------------------------------------------

int bench(const Options& opt) {
  const std::vector<const Case*> cases = chooseCases(opt.algos, opt.scaling);
  if (opt.scaling && opt.threads > 1)
    throw UsageError("--threads: the scaling mode runs on one thread (run the piles with --scenes bench/pile_10000 --threads N)");
  if (opt.scaling) return scaling(cases, opt.sizes, opt.steps, opt.repeat, opt.json);
  if (!opt.json.empty()) checkJsonPath(opt.json);
  if (opt.coreCheck && opt.threads < 2)
    throw UsageError("--core-check: it times the cases run on --threads N against each core alone; give --threads 2 or more");
  BenchPlan plan = planBench(opt.scenes, cases, opt.threads, opt.coreCheck ? allowedCores() : std::vector<int>{});
  TimedRuns t;
  t.source = printHeader(opt, plan.results);
  t.loadBefore = loadAverage();
  const auto started = Clock::now();
  timeRepeats(plan, opt.steps, opt.repeat);
  const bool allFinite = aggregate(plan.results);
  t.wall = since(started);
  t.loadAfter = loadAverage();
  std::cout << "\n";
  printTables(plan.results, opt.steps, std::cout);
  printNotes(plan, t);
  printWarnings(plan.results, allFinite);
  if (!opt.json.empty()) {
    writeJson(opt.json, benchJson(opt, plan, t));
    std::cout << "wrote " << opt.json << "\n";
  }
  if (!allFinite) return kExitNonFinite;
  return allRepeatable(plan.results) ? 0 : kExitNotRepeatable;
}

}  // namespace
}  // namespace substep::bench

int main(int argc, char** argv) {
  using namespace substep::bench;
  CLI::App app{"substep-bench: time substep's algorithms per stage on the benchmark scenes, next to Bullet"};
  Options opt;
  std::string algoHelp = "Cases to run, comma-separated (default:";
  for (const Case& c : allCases())
    if (c.byDefault) algoHelp += std::string(" ") + c.id;
  algoHelp += "; known:";
  for (const Case& c : allCases()) algoHelp += std::string(" ") + c.id;
  algoHelp += ")";
  auto* stepsOpt = app.add_option("--steps", opt.steps, "Steps per run (default 300; --quick: 10)")->check(CLI::Range(1, 10000000));
  app.add_option("--repeat", opt.repeat, "Runs of each case; the median is reported (default 5)")->check(CLI::Range(1, 1000));
  app.add_option("--scenes", opt.scenes,
                 "Scenes, comma-separated: names in assets/scenes or .json paths (default pyramid,chain,ragdoll_pile; "
                 "also e.g. pile)")
      ->delimiter(',');
  app.add_option("--algos", opt.algos, algoHelp)->delimiter(',');
  app.add_option("--json", opt.json, "Also write the results as JSON to FILE (written atomically)");
  app.add_option("--threads", opt.threads,
                 "Also run every substep case on N threads: the speed-up over one thread and whether the end states' "
                 "hashes are equal (default 1: single-threaded runs only)")
      ->check(CLI::Range(1, 256));
  app.add_flag("--core-check", opt.coreCheck,
               "With --threads N: after each N-thread run, the same case on one thread pinned to each core in turn; "
               "prints each core's own step time and the speed-up those speeds allow at best (on a shared virtual "
               "machine the cores may differ, and no code reaches N times one core); and, before each N-thread run, "
               "how long the first two cores take to hand a cache line over and back (cores far apart slow every "
               "hand-over between threads)");
  app.add_flag("--quick", opt.quick, "Smoke test: 10 steps per run unless --steps is given");
  app.add_flag("--scaling", opt.scaling,
               "Scaling mode: piles of --sizes boxes, the log-log slope of step time against the count and the "
               "peak memory per box (default cases a5-stack,bullet; 120 steps, 3 repeats unless given)");
  auto* repeatOpt = app.get_option("--repeat");
  app.add_option("--sizes", opt.sizes, "Scaling mode: pile sizes in boxes (default 100,300,1000,3000,10000)")
      ->delimiter(',')
      ->check(CLI::Range(1, 100000));
  return substep::app::runCommandLine(app, argc, argv, "substep-bench", [&] {
    if (opt.scaling && stepsOpt->count() == 0) opt.steps = 120;
    if (opt.scaling && repeatOpt->count() == 0) opt.repeat = 3;
    if (opt.quick && stepsOpt->count() == 0) opt.steps = 10;
    for (int i = 0; i < argc; ++i) opt.command += (i ? " " : "") + std::string(argv[i]);
    return bench(opt);
  });
}

// substep-bench: how fast each algorithm steps the benchmark scenes, where the time goes
// (s1 geometry, s2 formulation, s3 velocities, s4 coordinates), and what the speed buys
// (contact points, how far the bodies moved), next to Bullet stepping the same scene in the same
// process. See docs/benchmarks.md.
//
// Method: for each repeat, each scene and each case, a fresh World (or Bullet world) is built
// from the scene's initial state outside the timed loop, then stepped N times; every call of
// World::step() (or btDiscreteDynamicsWorld::stepSimulation(dt, 0)) is timed on its own with
// steady_clock, all N steps, no warm-up step left out. A run's time is the mean over its steps;
// the reported figure is the median over the repeats (the run with the median total, its stage
// split with it; with an even count the two middle runs averaged). Repeats are interleaved
// (repeat 1 of every case, then repeat 2, ...) so slow drift of the machine spreads over all
// cases. Single-threaded.
#include "app/bench/bullet_peer.h"
#include "physics/scene_file.h"
#include "physics/settings.h"
#include "physics/world.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

#ifndef SUBSTEP_SOURCE_DIR
#define SUBSTEP_SOURCE_DIR "."
#endif
#ifndef SUBSTEP_BUILD_TYPE
#define SUBSTEP_BUILD_TYPE "unknown"
#endif

namespace substep::bench {
namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

constexpr int kExitFailure = 1, kExitBadInput = 2, kExitNonFinite = 3;

struct BadInput : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// --- the cases --------------------------------------------------------------------------------

enum class Engine { Substep, Bullet };

struct Case {
  const char* id;          // its name for --algos
  const char* label;       // its name in the table
  Engine engine;
  Algorithm algorithm;     // substep cases
  int substeps;            // n (A3-A5; ignored by A1/A2)
  int iterations;          // A2: iteration cap; A3-A5: micro-iterations m; Bullet: solver iterations
  bool byDefault;          // run when --algos is not given
};

// Every case the benchmark knows, in table order. Adding one, or running one by default, is an
// edit of one line here. A case whose algorithm is not implemented yet stops the benchmark with
// a clear message before anything is timed, so keep those off by default until they land.
const std::vector<Case>& allCases() {
  static const std::vector<Case> list = {
      //  id        label             engine           algorithm      n  m   default
      {"a2",     "a2 (m=10)",      Engine::Substep, Algorithm::A2, 1, 10, true},
      {"a2-m4",  "a2 (m=4)",       Engine::Substep, Algorithm::A2, 1, 4,  false},  // solver work of a5 n=4 m=1
      {"a3",     "a3 (n=4 m=1)",   Engine::Substep, Algorithm::A3, 4, 1,  false},
      {"a4",     "a4 (n=4 m=1)",   Engine::Substep, Algorithm::A4, 4, 1,  false},
      {"a5",     "a5 (n=4 m=1)",   Engine::Substep, Algorithm::A5, 4, 1,  false},
      {"bullet", "bullet (10 it)", Engine::Bullet,  Algorithm::A2, 1, 10, true},
  };
  return list;
}

// The solver settings of a substep case: the case's algorithm, n and m with the algorithm's other
// defaults (resolve()); only the time step comes from the scene, so the scene's own solver block
// cannot change what a case means.
SolverSettings caseSettings(const Case& c, double dt) {
  SolverOverrides o;
  o.algorithm = c.algorithm;
  o.dt = dt;
  if (subSteps(c.algorithm)) o.substeps = c.substeps;
  o.iterations = c.iterations;
  return resolve(o);
}

// --- one run ----------------------------------------------------------------------------------

struct Run {
  StageTimes stages;        // mean per step [s]
  double total = 0;         // mean wall time of one step() call [s]
  double worst = 0;         // slowest single step [s]
  int stepsDone = 0;
  bool finite = true;
  std::string problem;      // when not finite: what the World said diverged
  int contacts = 0;         // contact points at the last step
  double moved = 0;         // largest displacement of a dynamic body from its start [m]
  int movedBody = -1;       // which body
  Vec3 movedBy = Vec3::Zero();  // its displacement [m]
  int solverIterations = 0, rows = 0;  // substep only: the last step's solver statistics
};

// Sets r.moved, r.movedBody and r.movedBy from the bodies' current centres.
template <class Position>
void measureDisplacement(Run& r, const Scene& scene, Position position) {
  for (size_t i = 0; i < scene.model.bodies.size(); ++i) {
    if (scene.model.bodies[i].isStatic) continue;
    const Vec3 d = position(i) - scene.initial.bodies[i].x;
    if (r.movedBody < 0 || d.norm() > r.moved) {
      r.moved = d.norm();
      r.movedBody = static_cast<int>(i);
      r.movedBy = d;
    }
  }
}

Run runSubstep(const Scene& scene, const SolverSettings& settings, int steps, std::vector<double>& stepTimes) {
  World world(scene.model, settings, scene.initial);  // outside the timed loop
  Run r;
  for (int k = 0; k < steps; ++k) {
    const auto t0 = Clock::now();
    const StepReport& rep = world.step();
    stepTimes[static_cast<size_t>(k)] = since(t0);
    r.stepsDone = k + 1;
    if (!rep.finite) {
      r.finite = false;
      r.problem = rep.problem;
      break;
    }
  }
  const double n = std::max(1, r.stepsDone);
  const StageTimes& t = world.totalTimes();
  r.stages = StageTimes{t.s1 / n, t.s2 / n, t.s3 / n, t.s4 / n};
  for (int k = 0; k < r.stepsDone; ++k) {
    r.total += stepTimes[static_cast<size_t>(k)];
    r.worst = std::max(r.worst, stepTimes[static_cast<size_t>(k)]);
  }
  r.total /= n;
  r.contacts = world.lastReport().contactPoints;
  r.solverIterations = world.lastReport().solver.iterations;
  r.rows = world.lastReport().solver.rows;
  measureDisplacement(r, scene, [&](size_t i) { return world.state().bodies[i].x; });
  return r;
}

Run runBullet(const Scene& scene, double dt, int iterations, int steps, std::vector<double>& stepTimes) {
  BulletPeer peer(scene.model, scene.initial, dt, iterations);  // outside the timed loop
  Run r;
  for (int k = 0; k < steps; ++k) {
    const auto t0 = Clock::now();
    peer.step();
    stepTimes[static_cast<size_t>(k)] = since(t0);
    r.stepsDone = k + 1;
  }
  r.finite = peer.finite();
  if (!r.finite) r.problem = "a Bullet body's position is not finite";
  const double n = std::max(1, r.stepsDone);
  for (int k = 0; k < r.stepsDone; ++k) {
    r.total += stepTimes[static_cast<size_t>(k)];
    r.worst = std::max(r.worst, stepTimes[static_cast<size_t>(k)]);
  }
  r.total /= n;
  r.contacts = peer.contactPoints();
  measureDisplacement(r, scene, [&](size_t i) { return peer.position(i); });
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
  bool repeatable = true;    // contacts and displacement the same in every repeat
  double ratio = NAN;        // median total / Bullet's median total on the same scene
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

std::string scenePath(const std::string& name) {
  if (name.find('/') != std::string::npos || (name.size() > 5 && name.substr(name.size() - 5) == ".json")) return name;
  const char* env = std::getenv("SUBSTEP_ASSETS");
  const std::string assets = env ? env : std::string(SUBSTEP_SOURCE_DIR) + "/assets";
  return assets + "/scenes/" + name + ".json";
}

std::string utcNow() {
  const std::time_t t = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return buf;
}

std::string cpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) {
      const auto colon = line.find(':');
      if (colon != std::string::npos) return line.substr(line.find_first_not_of(' ', colon + 1));
    }
  return "unknown CPU";
}

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

void printTable(const std::vector<Result>& results, std::ostream& out) {
  char line[256];
  std::snprintf(line, sizeof line, "%-8s %-15s %7s %7s %7s %7s %9s %9s %9s %9s\n", "scene", "algo", "s1", "s2", "s3",
                "s4", "total", "vs Bullet", "contacts", "moved");
  out << line;
  std::snprintf(line, sizeof line, "%-8s %-15s %7s %7s %7s %7s %9s %9s %9s %9s\n", "", "", "ms", "ms", "ms", "ms",
                "ms/step", "", "", "m");
  out << line;
  for (const Result& r : results) {
    const Run& m = r.median;
    const bool ours = r.c->engine == Engine::Substep;
    auto stage = [&](double s) { return ours ? fmt("%7.3f", s * 1e3) : std::string("      -"); };
    const std::string ratio = std::isnan(r.ratio) ? "-" : fmt("%.2fx", r.ratio);
    std::string moved = fmt("%.4f", m.moved);
    if (!m.finite) moved = "NaN@" + std::to_string(m.stepsDone);
    std::snprintf(line, sizeof line, "%-8s %-15s %s %s %s %s %9.3f %9s %9d %9s%s\n", r.scene.c_str(), r.c->label,
                  stage(m.stages.s1).c_str(), stage(m.stages.s2).c_str(), stage(m.stages.s3).c_str(),
                  stage(m.stages.s4).c_str(), m.total * 1e3, ratio.c_str(), m.contacts, moved.c_str(),
                  r.repeatable ? "" : "  (differs between repeats)");
    out << line;
  }
}

nlohmann::json runJson(const Run& r, const Model& model) {
  nlohmann::json j = {{"ms_per_step", {{"s1", r.stages.s1 * 1e3}, {"s2", r.stages.s2 * 1e3}, {"s3", r.stages.s3 * 1e3},
                           {"s4", r.stages.s4 * 1e3}, {"total", r.total * 1e3}}},
          {"worst_step_ms", r.worst * 1e3},
          {"steps_done", r.stepsDone},
          {"finite", r.finite},
          {"problem", r.problem},
          {"contact_points", r.contacts},
          {"moved_m", r.moved}};
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
  if (!fs::is_directory(dir, ec)) throw BadInput("--json " + path + ": folder " + dir.string() + " does not exist");
  if (access(dir.c_str(), W_OK) != 0) throw BadInput("--json " + path + ": cannot write in " + dir.string());
  if (fs::is_directory(target, ec)) throw BadInput("--json " + path + ": is a folder; give a file name");
}

// Written under a temporary name in the same folder, then renamed over `path`.
void writeJson(const std::string& path, const nlohmann::json& doc) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  std::error_code ec;
  const std::string temp = path + ".part" + std::to_string(getpid());
  {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    if (!out) throw BadInput("--json " + path + ": cannot create " + temp);
    out << doc.dump(2) << "\n";
    out.flush();
    if (!out) {
      out.close();
      std::remove(temp.c_str());
      throw std::runtime_error(path + ": write failed");
    }
  }
  fs::rename(temp, target, ec);
  if (ec) {
    std::remove(temp.c_str());
    throw std::runtime_error(path + ": cannot rename " + temp + " into place: " + ec.message());
  }
}

// --- main -------------------------------------------------------------------------------------

struct Options {
  int steps = 300;
  int repeat = 3;
  std::vector<std::string> scenes{"pyramid", "pile"};
  std::vector<std::string> algos;
  std::string json;
  bool quick = false;
};

int bench(const Options& opt) {
  std::vector<const Case*> cases;
  if (opt.algos.empty()) {
    for (const Case& c : allCases())
      if (c.byDefault) cases.push_back(&c);
  } else {
    for (const std::string& id : opt.algos) {
      const auto it = std::find_if(allCases().begin(), allCases().end(), [&](const Case& c) { return id == c.id; });
      if (it == allCases().end()) {
        std::string known;
        for (const Case& c : allCases()) known += std::string(known.empty() ? "" : ", ") + c.id;
        throw BadInput("--algos: unknown case \"" + id + "\"; known: " + known);
      }
      if (std::find(cases.begin(), cases.end(), &*it) == cases.end()) cases.push_back(&*it);
    }
  }

  if (!opt.json.empty()) checkJsonPath(opt.json);
  // Load every scene and check every case can be built, before anything is timed.
  std::vector<Scene> scenes;
  std::vector<std::string> names;
  std::vector<Result> results;
  for (const std::string& name : opt.scenes) {
    const std::string path = scenePath(name);
    try {
      scenes.push_back(loadScene(path));
    } catch (const SceneError& e) {
      throw BadInput(std::string("--scenes: ") + e.what());
    }
    names.push_back(std::filesystem::path(path).stem().string());
  }
  for (size_t s = 0; s < scenes.size(); ++s) {
    const double dt = scenes[s].solver.dt.value_or(1.0 / 60.0);
    for (const Case* c : cases) {
      Result r;
      r.scene = names[s];
      r.sceneIndex = s;
      r.c = c;
      if (c->engine == Engine::Substep) {
        try {
          r.settings = caseSettings(*c, dt);
          World probe(scenes[s].model, r.settings, scenes[s].initial);
        } catch (const std::invalid_argument& e) {
          throw BadInput(std::string("case ") + c->id + " on " + names[s] + ": " + e.what());
        }
      } else {
        const std::string why = bulletUnsupported(scenes[s].model);
        if (!why.empty()) {
          std::cerr << "substep-bench: no Bullet peer for " << names[s] << ": " << why << "\n";
          continue;
        }
        r.settings.dt = dt;
        r.settings.iterations = c->iterations;
      }
      results.push_back(std::move(r));
    }
  }

  std::cout << "substep-bench  " << utcNow() << "  " << cpuModel() << ", " << std::thread::hardware_concurrency()
            << " hardware threads, single-threaded runs; build " << SUBSTEP_BUILD_TYPE << "; Bullet "
            << bulletVersion() << "\n";
  std::cout << opt.steps << " steps of dt = " << fmt("%.6g", results.empty() ? 0.0 : results[0].settings.dt)
            << " s each, every step timed (no warm-up excluded); median of " << opt.repeat
            << " repeats, each on a freshly built world\n\n";
  std::cout.flush();

  std::vector<double> stepTimes(static_cast<size_t>(opt.steps));
  const int totalRuns = opt.repeat * static_cast<int>(results.size());
  int done = 0;
  for (int rep = 0; rep < opt.repeat; ++rep) {
    for (Result& r : results) {
      const Scene& scene = scenes[r.sceneIndex];
      Run run = r.c->engine == Engine::Substep ? runSubstep(scene, r.settings, opt.steps, stepTimes)
                                               : runBullet(scene, r.settings.dt, r.c->iterations, opt.steps, stepTimes);
      ++done;
      std::fprintf(stderr, "[%d/%d] %-8s %-15s repeat %d/%d: %.3f ms/step\n", done, totalRuns, r.scene.c_str(),
                   r.c->label, rep + 1, opt.repeat, run.total * 1e3);
      r.runs.push_back(run);
    }
  }

  bool allFinite = true;
  for (Result& r : results) {
    r.median = medianRun(r.runs);
    for (const Run& run : r.runs) {
      if (run.contacts != r.runs[0].contacts || run.moved != r.runs[0].moved || run.finite != r.runs[0].finite)
        r.repeatable = false;
      allFinite = allFinite && run.finite;
    }
  }
  for (Result& r : results) {
    for (const Result& b : results)
      if (b.scene == r.scene && b.c->engine == Engine::Bullet && b.median.total > 0)
        r.ratio = r.median.total / b.median.total;
  }

  std::cout << "\n";
  printTable(results, std::cout);
  std::cout << "\ns1 geometry, s2 formulation, s3 velocities, s4 coordinates: mean per step of the median run; total:\n"
               "wall time of one step() call (includes bookkeeping outside s1-s4). vs Bullet: total / Bullet's total\n"
               "on the same scene. contacts: contact points at the last step. moved: largest distance of any body's\n"
               "centre from where it started, after the last step (the pile is dropped, so there it is the fall).\n";
  if (!allFinite) {
    std::cout << "WARNING: some runs diverged (NaN@k: at step k):\n";
    for (const Result& r : results)
      if (!r.median.finite) std::cout << "  " << r.scene << " " << r.c->label << ": " << r.median.problem << "\n";
  }

  if (!opt.json.empty()) {
    nlohmann::json doc;
    doc["tool"] = "substep-bench";
    doc["date_utc"] = utcNow();
    doc["machine"] = {{"cpu", cpuModel()}, {"hardware_threads", std::thread::hardware_concurrency()}};
    doc["build_type"] = SUBSTEP_BUILD_TYPE;
    doc["bullet_version"] = bulletVersion();
    doc["steps"] = opt.steps;
    doc["repeat"] = opt.repeat;
    doc["method"] =
        "every step timed with steady_clock, no warm-up excluded; run = mean over its steps; "
        "reported = median over repeats (run with the median total); fresh world per repeat; repeats interleaved";
    nlohmann::json list = nlohmann::json::array();
    for (const Result& r : results) {
      const Model& model = scenes[r.sceneIndex].model;
      nlohmann::json j = runJson(r.median, model);
      j["scene"] = r.scene;
      j["case"] = r.c->id;
      j["label"] = r.c->label;
      j["engine"] = r.c->engine == Engine::Substep ? "substep" : "bullet";
      if (r.c->engine == Engine::Substep) {
        const SolverSettings& s = r.settings;
        j["settings"] = {{"algorithm", algorithmName(s.algorithm)}, {"dt", s.dt},       {"substeps", s.substeps},
                         {"iterations", s.iterations},              {"omega", s.omega}, {"tolerance", s.tolerance},
                         {"kappa", s.kappa},                        {"tau", s.tau},     {"warm_start", s.warmStart},
                         {"block_solve", s.blockSolve},             {"slop", s.slop}};
        j["solver_last_step"] = {{"iterations", r.median.solverIterations}, {"rows", r.median.rows}};
      } else {
        j["settings"] = {{"dt", r.settings.dt}, {"iterations", r.c->iterations}, {"sleeping", false}};
      }
      j["vs_bullet"] = std::isnan(r.ratio) ? nlohmann::json(nullptr) : nlohmann::json(r.ratio);
      j["repeatable"] = r.repeatable;
      nlohmann::json reps = nlohmann::json::array();
      for (const Run& run : r.runs) reps.push_back(runJson(run, model));
      j["repeats"] = reps;
      list.push_back(j);
    }
    doc["results"] = list;
    writeJson(opt.json, doc);
    std::cout << "wrote " << opt.json << "\n";
  }
  return allFinite ? 0 : kExitNonFinite;
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
  app.add_option("--repeat", opt.repeat, "Runs of each case; the median is reported (default 3)")->check(CLI::Range(1, 1000));
  app.add_option("--scenes", opt.scenes, "Scenes, comma-separated: names in assets/scenes or .json paths (default pyramid,pile)")
      ->delimiter(',');
  app.add_option("--algos", opt.algos, algoHelp)->delimiter(',');
  app.add_option("--json", opt.json, "Also write the results as JSON to FILE (written atomically)");
  app.add_flag("--quick", opt.quick, "Smoke test: 10 steps per run unless --steps is given");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : kExitBadInput;
  }
  if (opt.quick && stepsOpt->count() == 0) opt.steps = 10;
  try {
    return bench(opt);
  } catch (const BadInput& e) {
    std::cerr << "substep-bench: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << "substep-bench: " << e.what() << "\n";
    return kExitFailure;
  }
}

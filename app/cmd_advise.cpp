// substep advise: the cheapest solver settings that meet an accuracy target on a scene
// (lab/advise.h), with the runner-up, the margin and the `substep run` line that reproduces it.
#include "app/commands.h"
#include "app/common.h"
#include "lab/advise.h"
#include "lab/record.h"

#include <cmath>
#include <iomanip>
#include <iostream>
#include <sstream>

namespace substep::app {

namespace {

using nlohmann::json;

struct AdviseCmdOptions {
  std::string scene;
  std::optional<std::string> maxError, maxPenetration, maxJointError, stand;
  std::optional<double> seconds;
  std::string methods;
  int repeat = 3, budget = 400;
  bool json = false, quiet = false;
  SceneLimits limits;
};

// The `substep run` options that give exactly these settings on this scene: the method's own,
// and every setting where the scene's solver block would otherwise differ.
std::string runLine(const std::string& scenePathText, const Scene& scene, const lab::Method& m, const SolverSettings& want,
                    double seconds) {
  SolverOverrides cl = m.overrides;
  cl.set(&SolverSettings::dt, want.dt);
  for (int round = 0; round < 3; ++round) {
    const SolverSettings got = resolveSettings(scene, cl);
    bool same = true;
    for (const SettingSpec& spec : settingTable())
      if (spec.resolved() && spec.takes.has(want.algorithm) && spec.get(got) != spec.get(want)) {
        cl.set(spec, spec.get(want));
        same = false;
      }
    if (same) break;
  }
  return "substep run " + scenePathText + flagsText(cl) + " --seconds " + numberText(seconds);
}

std::string costText(const lab::RunResult& r) {
  std::ostringstream o;
  o << std::setprecision(3) << r.cost.msPerStep << " ms/step at h = " << stepText(r.settings.dt) << ", " << r.msPerSecond()
    << " ms per simulated second";
  return o.str();
}

std::string valueText(const lab::Candidate& c, const std::vector<lab::Target>& targets) {
  std::string t;
  for (const lab::Target& target : targets) {
    if (target.metric == "stand") {
      t += std::string(t.empty() ? "" : ", ") + "largest displacement " + lab::formatLength(c.run.metrics.displacementMax);
      continue;
    }
    const std::optional<double> v = lab::metricValue(c.run.metrics, target.metric);
    if (v) t += (t.empty() ? "" : ", ") + std::string(lab::metricLabel(target.metric)) + " " + lab::formatMetric(target.metric, *v);
  }
  return t;
}

// How far under the first target the candidate stays: 38 % for 0.62 cm against 1 cm.
double margin(const lab::Candidate& c, const lab::Target& t) {
  if (t.metric == "stand") return NAN;
  return 1 - c.value / t.bound;
}

// --- the plan: targets and candidates checked before the first run ----------------------------

std::vector<lab::Target> adviseTargets(const AdviseCmdOptions& o, const Scene& scene) {
  std::vector<lab::Target> targets;
  auto add = [&](const std::optional<std::string>& text, const std::string& metric, const char* flag) {
    if (!text) return;
    const std::string unit = metric == "stand" ? "s" : lab::metricUnit(metric);
    try {
      targets.push_back({metric, lab::parseQuantity(*text, unit)});
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string(flag) + ": " + e.what());
    }
  };
  add(o.maxError, lab::errorMetric(scene), "--max-error");
  add(o.maxPenetration, "penetration", "--max-penetration");
  add(o.maxJointError, "joint_error", "--max-joint-error");
  add(o.stand, "stand", "--stand");
  if (targets.empty()) throw UsageError("give a target: --max-error, --max-penetration, --max-joint-error or --stand");
  if (o.maxJointError && scene.model.joints.empty()) throw UsageError("--max-joint-error: " + scene.file + " has no joints");
  return targets;
}

std::vector<lab::Method> candidates(const lab::AdviseOptions& ao) {
  return ao.candidates.empty() ? lab::defaultCandidates() : ao.candidates;
}

// The search: --stand gives the runs' length, else --seconds, else the scene's criteria, else 5 s.
lab::AdviseOptions adviseOptions(const AdviseCmdOptions& o, const Scene& scene, std::vector<lab::Target> targets) {
  lab::AdviseOptions ao;
  ao.targets = std::move(targets);
  ao.seconds = o.stand ? ao.targets.back().bound : o.seconds ? *o.seconds : scene.criteria ? scene.criteria->seconds : 5.0;
  if (o.stand && o.seconds) throw UsageError("--seconds: --stand gives the run's length");
  ao.repeat = o.repeat;
  ao.budget = o.budget;
  if (!o.methods.empty()) try {
      ao.candidates = lab::parseMethods(o.methods);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--methods: ") + e.what());
    }
  for (const lab::Method& m : candidates(ao)) try {
      lab::methodSettings(m, scene);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--methods: ") + m.text + ": " + e.what());
    }
  return ao;
}

void printAdviseHeader(const Scene& scene, const lab::AdviseOptions& ao) {
  std::cout << "scene     " << scene.file << " (" << scene.model.dynamicCount() << " dynamic bodies, " << scene.model.joints.size()
            << " joints), " << numberText(ao.seconds) << " s per run\n";
  for (const lab::Target& t : ao.targets) std::cout << "target    " << t.text() << "\n";
}

// --- the search -------------------------------------------------------------------------------

lab::Advice search(const Scene& scene, const lab::AdviseOptions& ao, bool showProgress) {
  Progress progress("advise", static_cast<long long>(candidates(ao).size()), showProgress);
  lab::Advice a;
  try {
    a = lab::advise(scene, ao, [&](size_t done, size_t, const lab::Candidate&) {
      if (InterruptGuard::interrupted()) throw Interrupted();
      progress.update(static_cast<long long>(done));
    });
  } catch (const lab::ReferenceError& e) {
    throw UsageError(scene.file + ": criteria.reference: " + e.what());
  }
  progress.finish();
  return a;
}

const lab::Candidate* tried(const lab::Advice& a, int index) {
  return index >= 0 ? &a.tried[static_cast<size_t>(index)] : nullptr;
}

std::string searchedText(const lab::Advice& a, int budget) {
  int stoppedEarly = 0;
  for (const lab::Candidate& c : a.tried) stoppedEarly += !c.run.stoppedEarly.empty();
  return std::to_string(a.searched) + " of " + std::to_string(a.total) + " settings, cheapest first" +
         (a.budgetSpent ? " (the budget of " + std::to_string(budget) + " runs was spent)" : "") + "; " +
         std::to_string(stoppedEarly) + " runs stopped when they missed";
}

// --- the answer -------------------------------------------------------------------------------

json candidateJson(const lab::Candidate* c, const AdviseCmdOptions& o, const Scene& scene, const lab::AdviseOptions& ao) {
  if (!c) return nullptr;
  const double m = margin(*c, ao.targets.front());
  return {{"method", c->method.text},
          {"ms_per_step", c->run.cost.msPerStep},
          {"ms_per_second", c->run.msPerSecond()},
          {"dt", c->run.settings.dt},
          {"value", std::isfinite(c->value) ? json(c->value) : json(nullptr)},
          {"margin", std::isfinite(m) ? json(m) : json(nullptr)},
          {"missed", c->missed.empty() ? json(nullptr) : json(c->missed)},
          {"run", runLine(o.scene, scene, c->method, c->run.settings, ao.seconds)}};
}

int printAdviceJson(const lab::Advice& a, const AdviseCmdOptions& o, const Scene& scene, const lab::AdviseOptions& ao) {
  const lab::Candidate *best = tried(a, a.best), *second = tried(a, a.runnerUp);
  json targets = json::array();
  for (const lab::Target& t : ao.targets) targets.push_back({{"metric", t.metric}, {"at_most", t.bound}, {"text", t.text()}});
  json j = {{"scene", scene.file}, {"seconds", ao.seconds}, {"targets", targets}, {"met", best != nullptr},
            {"best", candidateJson(best, o, scene, ao)}, {"runner_up", candidateJson(second, o, scene, ao)},
            {"closest", candidateJson(tried(a, a.closest), o, scene, ao)},
            {"searched", a.searched}, {"candidates", a.total}, {"budget_spent", a.budgetSpent}};
  if (best && second) j["runner_up_cost_ratio"] = second->run.msPerSecond() / best->run.msPerSecond();
  std::cout << j.dump(2) << "\n";
  return best ? 0 : kExitFailure;
}

void printNoneMet(const lab::Candidate* closest, const std::vector<lab::Target>& targets) {
  std::cout << "nothing   within the searched range meets " << targets.front().text();
  if (closest) std::cout << "; the closest was " << closest->method.text << " (" << closest->missed << ")";
  std::cout << "\n";
}

void printBest(const lab::Candidate& best, const lab::Candidate* second, const std::vector<lab::Target>& targets) {
  std::cout << std::fixed << std::setprecision(0);
  std::cout << "best      " << best.method.text << "\n          " << costText(best.run) << "; " << valueText(best, targets);
  if (std::isfinite(margin(best, targets.front()))) std::cout << " (" << 100 * margin(best, targets.front()) << " % under the target)";
  std::cout << "\n";
  if (second) {
    std::cout << "runner-up " << second->method.text << "\n          " << costText(second->run) << " (" << std::setprecision(2)
              << second->run.msPerSecond() / best.run.msPerSecond() << "x the best's cost); " << valueText(*second, targets) << "\n";
  } else {
    std::cout << "runner-up none met the target within the search\n";
  }
}

int printAdvice(const lab::Advice& a, const AdviseCmdOptions& o, const Scene& scene, const lab::AdviseOptions& ao) {
  if (!o.quiet) std::cout << "searched  " << searchedText(a, o.budget) << "\n";
  const lab::Candidate* best = tried(a, a.best);
  if (!best) {
    printNoneMet(tried(a, a.closest), ao.targets);
    return kExitFailure;
  }
  printBest(*best, tried(a, a.runnerUp), ao.targets);
  std::cout << "run it    " << runLine(o.scene, scene, best->method, best->run.settings, ao.seconds) << "\n";
  return 0;
}

int runAdvise(const AdviseCmdOptions& o) {
  const Scene scene = load(o.scene, o.limits);
  const lab::AdviseOptions ao = adviseOptions(o, scene, adviseTargets(o, scene));
  const bool text = !o.quiet && !o.json;
  if (text) printAdviseHeader(scene, ao);
  InterruptGuard interrupt;
  const lab::Advice a = search(scene, ao, text);
  return o.json ? printAdviceJson(a, o, scene, ao) : printAdvice(a, o, scene, ao);
}

}  // namespace

void addAdviseCommand(CLI::App& app, std::function<int()>& action) {
  auto opt = std::make_shared<AdviseCmdOptions>();
  CLI::App* cmd = app.add_subcommand("advise", "Find the cheapest solver settings that meet an accuracy target on a scene");
  cmd->footer(
      "\nSearches algorithm, n, m, h, kappa, tau and warm starting (or the grid of --methods), cheapest first by estimated\n"
      "work; each run stops when it misses; the ones that meet the target are timed (median of --repeat) and ranked by\n"
      "cost per simulated second. Quantities take units: 1cm, 5mm, 2deg, 2%, 60s. Exit status 1 when nothing meets it.");
  cmd->add_option("scene", opt->scene, "Scene file (JSON)")->required();
  cmd->add_option("--max-error", opt->maxError, "At most this error: the scene's error measure (its criteria, else trajectory or "
                                                 "joint error, else penetration), e.g. 1cm");
  cmd->add_option("--max-penetration", opt->maxPenetration, "At most this deepest contact penetration, e.g. 5mm");
  cmd->add_option("--max-joint-error", opt->maxJointError, "At most this largest joint anchor separation, e.g. 1cm");
  cmd->add_option("--stand", opt->stand, "Stand this long: no body moves beyond the scene's tolerance (criteria.tolerance, else "
                                         "the failure watch's collapse), e.g. 60s");
  cmd->add_option("--seconds", opt->seconds, "Simulated time of each run [s] (default: the scene's criteria, else 5)")
      ->check(finiteIn(1e-3, 3600));
  cmd->add_option("--methods", opt->methods, "The candidates, as method specs with value lists (default: the built-in search)");
  cmd->add_option("--repeat", opt->repeat, "Timed runs of a candidate that meets the target (default 3)")->check(CLI::Range(1, 100));
  cmd->add_option("--budget", opt->budget, "Candidates run at most (default 400)")->check(CLI::Range(1, 100000));
  cmd->add_flag("--json", opt->json, "Print the answer as JSON");
  cmd->add_flag("--quiet,-q", opt->quiet, "Print the answer only (no progress, no header)");
  addMaxBodies(*cmd, opt->limits);
  cmd->callback([opt, &action] { action = [opt] { return runAdvise(*opt); }; });
}

}  // namespace substep::app

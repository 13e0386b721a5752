// substep advise: the cheapest solver settings that meet an accuracy target on a scene
// (lab/advise.h), with the runner-up, the margin and the `substep run` line that reproduces it.
#include "app/commands.h"
#include "app/common.h"
#include "lab/advise.h"
#include "lab/record.h"
#include "lab/verdict.h"

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
  int repeat = 3, maxRuns = 0;
  std::string budget = "60s";
  bool json = false, quiet = false, criteria = false;
  SceneLimits limits;
};

// The `substep run` options that give exactly these settings on this scene: the method's own,
// and every setting where the scene's solver block would otherwise differ; a peer's spec as it is.
std::string runLine(const std::string& scenePathText, const Scene& scene, const lab::Method& m, const SolverSettings& want,
                    double seconds) {
  if (m.isPeer())  // the peer's own keys are in its spec; run --method takes it as the sweep ran it
    return "substep run " + scenePathText + " --method " + m.text +
           (m.overrides.get(&SolverSettings::dt) ? "" : " --dt " + stepText(want.dt)) + " --seconds " + numberText(seconds);
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

std::string valueText(const lab::Candidate& c, const std::vector<lab::Target>& targets, const Scene& scene) {
  std::string t;
  for (const lab::Target& target : targets) {
    if (target.metric == "criteria") {
      t += std::string(t.empty() ? "" : ", ") + lab::judge(scene, c.run).figure;
      continue;
    }
    if (target.metric == "stand") {
      t += std::string(t.empty() ? "" : ", ") + "largest displacement " + lab::formatLength(c.run.metrics.displacementMax);
      continue;
    }
    const std::optional<double> v = lab::metricValue(c.run.metrics, target.metric);
    if (v) t += (t.empty() ? "" : ", ") + std::string(lab::metricLabel(target.metric)) + " " + lab::formatMetric(target.metric, *v);
  }
  return t;
}

// How far the candidate is from the first target's bound, as a share of it: 38 % under for
// 0.62 cm against at most 1 cm. For the scene's criteria, that of the check its figure shows:
// under an at-most bound, above an at-least one, none for a yes-or-no check (a body stays in its
// box); none for standing.
struct Margin {
  double share = NAN;
  std::string text;  // "38 % under the target", "26 % above its bound"; empty for none
};

Margin margin(const lab::Candidate& c, const lab::Target& t, const Scene& scene) {
  Margin m;
  const char* side = "under";
  if (t.metric == "stand") return m;
  if (t.metric == "criteria") {
    const lab::Verdict v = lab::judge(scene, c.run);
    if (v.decisive < 0) return m;
    const lab::Check& k = v.checks[static_cast<size_t>(v.decisive)];
    m.share = lab::checkMargin(k);
    if (k.kind == lab::Check::Kind::AtLeast) side = "above";
  } else {
    m.share = 1 - c.value / t.bound;
  }
  if (!std::isfinite(m.share)) return Margin{};
  std::ostringstream text;
  text << std::fixed << std::setprecision(0) << 100 * m.share << " % " << side << (t.metric == "criteria" ? " its bound" : " the target");
  m.text = text.str();
  return m;
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
  // A scene that states no error measure: the trajectory against a converged reference.
  add(o.maxError, lab::statedErrorMetric(scene).value_or("trajectory_error"), "--max-error");
  add(o.maxPenetration, "penetration", "--max-penetration");
  add(o.maxJointError, "joint_error", "--max-joint-error");
  add(o.stand, "stand", "--stand");
  // A scene that states its own checks is advised on them when no other target is given.
  const bool hasChecks = scene.criteria && lab::hasChecks(*scene.criteria);
  if (o.criteria && !hasChecks) throw UsageError("--criteria: " + scene.file + " states no criteria.pass (nor moving, stay_in, turns) to pass");
  if (o.criteria || (targets.empty() && hasChecks)) targets.insert(targets.begin(), lab::Target{"criteria", 0});
  if (targets.empty())
    throw UsageError("give a target: --max-error, --max-penetration, --max-joint-error or --stand (" + scene.file +
                     " has no criteria of its own to pass)");
  if (o.maxJointError && scene.model.joints.empty()) throw UsageError("--max-joint-error: " + scene.file + " has no joints");
  return targets;
}

std::vector<lab::Method> candidates(const lab::AdviseOptions& ao) {
  return ao.candidates.empty() ? lab::defaultCandidates() : ao.candidates;
}

// The search: --stand gives the runs' length, else --seconds, else the scene's criteria, else 5 s.
// A reference it had to compute is kept in `found`, to be said.
lab::AdviseOptions adviseOptions(const AdviseCmdOptions& o, const Scene& scene, std::vector<lab::Target> targets,
                                 std::optional<lab::FoundReference>& found) {
  lab::AdviseOptions ao;
  ao.targets = std::move(targets);
  ao.seconds = o.stand ? ao.targets.back().bound : o.seconds ? *o.seconds : scene.criteria ? scene.criteria->seconds : 5.0;
  if (o.stand && o.seconds) throw UsageError("--seconds: --stand gives the run's length");
  ao.repeat = o.repeat;
  ao.maxRuns = o.maxRuns;
  try {
    ao.timeBudget = lab::parseQuantity(o.budget, "s");
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--budget: ") + e.what());
  }
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
  // Last, once the input is known good: it takes seconds, and they count against the budget
  // (lab::TimeBudgetSpent, exit 1, when they are all of it).
  if (o.maxError && !lab::statedErrorMetric(scene)) try {
      if (!o.quiet && !o.json) std::cerr << "substep advise: " << scene.file << " states no reference; computing a converged one\n";
      found = lab::findConvergedReference(scene, ao.seconds, ao.timeBudget);
      ao.reference = found->prepared;
      ao.budgetUsed = found->seconds;
    } catch (const lab::ReferenceError& e) {
      throw UsageError(std::string("--max-error: ") + e.what());
    }
  return ao;
}

// "a1:h=1/960 (halving h moved it 0.21 mm, 0.03 % of the motion), computed in 1.3 s"
std::string referenceText(const lab::FoundReference& f) {
  const lab::ConvergedReference& c = *f.prepared.converged;
  std::ostringstream t;
  t << f.reference.method << " (halving h moved it " << lab::formatLength(c.change) << ", " << std::setprecision(2)
    << 100 * c.change / std::max(c.motion, 1e-300) << " % of the motion), computed in " << std::fixed << std::setprecision(1) << f.seconds
    << " s";
  if (!f.rejected.empty()) t << " after " << f.rejected.size() << " that did not converge";
  return t.str();
}

void printAdviseHeader(const Scene& scene, const lab::AdviseOptions& ao, const std::optional<lab::FoundReference>& found) {
  std::cout << "scene     " << scene.file << " (" << scene.model.dynamicCount() << " dynamic bodies, " << scene.model.joints.size()
            << " joints), " << numberText(ao.seconds) << " s per run\n";
  if (found) std::cout << "reference " << referenceText(*found) << "\n";
  for (const lab::Target& t : ao.targets) std::cout << "target    " << t.text(&scene) << "\n";
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

std::string searchedText(const lab::Advice& a) {
  int stoppedEarly = 0;
  for (const lab::Candidate& c : a.tried) stoppedEarly += !c.run.stoppedEarly.empty();
  std::ostringstream t;
  t << a.searched << " of " << a.total << " settings in " << std::fixed << std::setprecision(1) << a.seconds
    << " s, climbing each method's h, n and m from its cheapest; " << stoppedEarly << " runs stopped when they missed";
  return t.str();
}

// What the budget left out and how to search it: "12 settings not run when the budget (60 s) ran
// out, the cheapest a5:...; search them with --budget 180s".
std::string notRunText(const lab::Advice& a, const lab::AdviseOptions& ao) {
  if (!a.budgetSpent) return "";
  const bool byRuns = ao.maxRuns > 0 && a.searched >= static_cast<size_t>(ao.maxRuns);
  std::ostringstream t;
  t << a.notRun.size() << " settings not run when the budget ("
    << (byRuns ? std::to_string(ao.maxRuns) + " runs" : numberText(ao.timeBudget) + " s") << ") ran out, the cheapest "
    << (a.notRun.empty() ? "-" : a.notRun.front().text) << "; search them with ";
  if (byRuns) {
    t << "--max-runs 0";
  } else {
    // The runs left are the costlier ones: at least twice the time, more the more is left.
    const double share = static_cast<double>(a.searched + a.notRun.size()) / static_cast<double>(std::max<size_t>(a.searched, 1));
    t << "--budget " << numberText(std::ceil(ao.timeBudget * std::max(2.0, 1.5 * share))) << "s";
  }
  return t.str();
}

// --- the answer -------------------------------------------------------------------------------

json candidateJson(const lab::Candidate* c, const AdviseCmdOptions& o, const Scene& scene, const lab::AdviseOptions& ao) {
  if (!c) return nullptr;
  const Margin m = margin(*c, ao.targets.front(), scene);
  return {{"method", c->method.text},
          {"ms_per_step", c->run.cost.msPerStep},
          {"ms_per_second", c->run.msPerSecond()},
          {"dt", c->run.settings.dt},
          {"value", std::isfinite(c->value) ? json(c->value) : json(nullptr)},
          {"margin", m.text.empty() ? json(nullptr) : json(m.share)},
          {"margin_text", m.text.empty() ? json(nullptr) : json(m.text)},
          {"missed", c->missed.empty() ? json(nullptr) : json(c->missed)},
          {"run", runLine(o.scene, scene, c->method, c->run.settings, ao.seconds)}};
}

int printAdviceJson(const lab::Advice& a, const AdviseCmdOptions& o, const Scene& scene, const lab::AdviseOptions& ao,
                    const std::optional<lab::FoundReference>& found) {
  const lab::Candidate *best = tried(a, a.best), *second = tried(a, a.runnerUp);
  json targets = json::array();
  for (const lab::Target& t : ao.targets)
    targets.push_back({{"metric", t.metric}, {"at_most", t.metric == "criteria" ? json(nullptr) : json(t.bound)}, {"text", t.text(&scene)}});
  json j = {{"scene", scene.file}, {"seconds", ao.seconds}, {"targets", targets}, {"met", best != nullptr},
            {"best", candidateJson(best, o, scene, ao)}, {"runner_up", candidateJson(second, o, scene, ao)},
            {"closest", candidateJson(tried(a, a.closest), o, scene, ao)},
            {"searched", a.searched}, {"candidates", a.total}, {"search_seconds", a.seconds}, {"budget_spent", a.budgetSpent},
            {"not_run", a.notRun.size()}};
  if (a.budgetSpent) j["not_run_note"] = notRunText(a, ao);
  if (found)
    j["reference"] = {{"method", found->reference.method}, {"dt", found->prepared.converged->dt},
                      {"change", found->prepared.converged->change}, {"motion", found->prepared.converged->motion},
                      {"seconds", found->seconds}, {"rejected", found->rejected}, {"text", referenceText(*found)}};
  if (best && second) j["runner_up_cost_ratio"] = second->run.msPerSecond() / best->run.msPerSecond();
  std::cout << j.dump(2) << "\n";
  return best ? 0 : kExitFailure;
}

void printNoneMet(const lab::Advice& a, const lab::AdviseOptions& ao, const Scene& scene) {
  const lab::Candidate* closest = tried(a, a.closest);
  // "meets max joint error <= 1.00 cm", "passes the scene's criteria: ..."
  const lab::Target& t = ao.targets.front();
  std::cout << "nothing   " << (a.budgetSpent ? "run within the budget" : "in the searched space") << (t.metric == "criteria" ? " " : " meets ")
            << t.text(&scene);
  if (closest) std::cout << "; the closest was " << closest->method.text << " (" << closest->missed << ")";
  std::cout << "\n";
}

void printBest(const lab::Candidate& best, const lab::Candidate* second, const std::vector<lab::Target>& targets, const Scene& scene) {
  std::cout << std::fixed << std::setprecision(0);
  std::cout << "best      " << best.method.text << "\n          " << costText(best.run) << "; " << valueText(best, targets, scene);
  const Margin m = margin(best, targets.front(), scene);
  if (!m.text.empty()) std::cout << " (" << m.text << ")";
  std::cout << "\n";
  if (second) {
    std::cout << "runner-up " << second->method.text << "\n          " << costText(second->run) << " (" << std::setprecision(2)
              << second->run.msPerSecond() / best.run.msPerSecond() << "x the best's cost); " << valueText(*second, targets, scene) << "\n";
  } else {
    std::cout << "runner-up none met the target within the search\n";
  }
}

int printAdvice(const lab::Advice& a, const AdviseCmdOptions& o, const Scene& scene, const lab::AdviseOptions& ao) {
  if (!o.quiet) std::cout << "searched  " << searchedText(a) << "\n";
  if (a.budgetSpent) std::cout << "not run   " << notRunText(a, ao) << "\n";
  const lab::Candidate* best = tried(a, a.best);
  if (!best) {
    printNoneMet(a, ao, scene);
    return kExitFailure;
  }
  printBest(*best, tried(a, a.runnerUp), ao.targets, scene);
  std::cout << "run it    " << runLine(o.scene, scene, best->method, best->run.settings, ao.seconds) << "\n";
  return 0;
}

int runAdvise(const AdviseCmdOptions& o) {
  const Scene scene = load(o.scene, o.limits);
  std::optional<lab::FoundReference> found;
  const lab::AdviseOptions ao = adviseOptions(o, scene, adviseTargets(o, scene), found);
  const bool text = !o.quiet && !o.json;
  if (text) printAdviseHeader(scene, ao, found);
  InterruptGuard interrupt;
  const lab::Advice a = search(scene, ao, text);
  return o.json ? printAdviceJson(a, o, scene, ao, found) : printAdvice(a, o, scene, ao);
}

}  // namespace

void addAdviseCommand(CLI::App& app, std::function<int()>& action) {
  auto opt = std::make_shared<AdviseCmdOptions>();
  CLI::App* cmd = app.add_subcommand("advise", "Find the cheapest solver settings that meet an accuracy target on a scene");
  cmd->footer(
      "\nSearches algorithm, n, m, h, kappa, tau and warm starting (or the grid of --methods) within --budget of wall time:\n"
      "each method's h, n and m climbed from its cheapest by doubling, then bisected, the cheapest probe of all first, then\n"
      "the rest cheapest first by estimated work; each run stops when it misses; those that meet the target are ranked by\n"
      "cost per simulated second, the two cheapest timed again (median of --repeat). Quantities take units: 1cm, 5mm, 2deg, 2%, 60s. Exit status 1 when nothing meets it.");
  cmd->add_option("scene", opt->scene, "Scene file (JSON)")->required();
  cmd->add_option("--max-error", opt->maxError, "At most this error: the scene's error measure (its criteria), else the trajectory's "
                                                 "distance from a converged reference computed first (A1, else A3, at a small h), e.g. 1cm");
  cmd->add_option("--max-penetration", opt->maxPenetration, "At most this deepest contact penetration, e.g. 5mm");
  cmd->add_option("--max-joint-error", opt->maxJointError, "At most this largest joint anchor separation, e.g. 1cm");
  cmd->add_flag("--criteria", opt->criteria, "Pass the scene's own criteria (its \"pass\" bounds and checks, as the atlas judges); "
                                            "the default target when no other is given and the scene has them");
  cmd->add_option("--stand", opt->stand, "Stand this long: no body moves beyond the scene's tolerance (criteria.tolerance, else "
                                         "the failure watch's collapse), e.g. 60s");
  cmd->add_option("--seconds", opt->seconds, "Simulated time of each run [s] (default: the scene's criteria, else 5)")
      ->check(finiteIn(1e-3, 3600));
  cmd->add_option("--methods", opt->methods, "The candidates, as method specs with value lists (default: the built-in search)");
  cmd->add_option("--repeat", opt->repeat, "Timed runs of each of the two cheapest that meet the target (default 3)")->check(CLI::Range(1, 100));
  cmd->add_option("--budget", opt->budget,
                  "Wall time for the search, e.g. 60s or 5min (default 60s); the run going on then finishes, and what was not "
                  "run is listed");
  cmd->add_option("--max-runs", opt->maxRuns, "Candidates run at most (default 0: as many as the time allows)")
      ->check(CLI::Range(0, 100000000));
  cmd->add_flag("--json", opt->json, "Print the answer as JSON");
  cmd->add_flag("--quiet,-q", opt->quiet, "Print the answer only (no progress, no header)");
  addMaxBodies(*cmd, opt->limits);
  cmd->callback([opt, &action] { action = [opt] { return runAdvise(*opt); }; });
}

}  // namespace substep::app

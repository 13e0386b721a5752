#include "lab/advise.h"

#include "lab/verdict.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <map>
#include <stdexcept>

namespace substep::lab {

std::string Target::text(const Scene* scene) const {
  if (metric == "criteria") {
    std::string t = "passes the scene's criteria";
    if (!scene || !scene->criteria) return t;
    const char* sep = ": ";
    for (const auto& [name, at] : scene->criteria->pass) t += sep + std::string(metricLabel(name)) + " <= " + formatMetric(name, at), sep = ", ";
    const SceneCriteria& c = *scene->criteria;
    if (c.moving) t += sep + std::string("the sliding bodies move at least ") + formatLength(c.moving->atLeast), sep = ", ";
    if (c.stayIn) t += sep + std::string("a body stays inside its box"), sep = ", ";
    if (c.turns) t += sep + std::string("a body turns at least ") + formatMetric("joint_angle_error", c.turns->atLeast);
    return t;
  }
  if (metric == "stand") return "stands for " + numberText(bound) + " s (no body moves beyond the scene's tolerance, no divergence)";
  return std::string(metricLabel(metric)) + " <= " + formatMetric(metric, bound);
}

double parseQuantity(const std::string& raw, const std::string& unit) {
  std::string text;
  for (char c : raw)
    if (c != ' ') text += c;
  const char* begin = text.c_str();
  char* end = nullptr;
  const double x = text.empty() ? NAN : std::strtod(begin, &end);
  const std::string suffix = end ? std::string(end) : "";
  std::map<std::string, double> scale;
  std::string expected;
  if (unit == "m") {
    scale = {{"", 1}, {"m", 1}, {"cm", 1e-2}, {"mm", 1e-3}, {"um", 1e-6}};
    expected = "a length such as 1cm, 5mm or 0.01 (metres)";
  } else if (unit == "rad") {
    scale = {{"", 1}, {"rad", 1}, {"deg", M_PI / 180}};
    expected = "an angle such as 2deg or 0.03 (radians)";
  } else if (unit == "s") {
    scale = {{"", 1}, {"s", 1}, {"ms", 1e-3}, {"min", 60}};
    expected = "a time such as 60s or 2min";
  } else if (unit == "m/s") {
    scale = {{"", 1}, {"m/s", 1}, {"cm/s", 1e-2}, {"mm/s", 1e-3}};
    expected = "a speed such as 5cm/s or 0.05 (m/s)";
  } else {
    scale = {{"", 1}, {"%", 1e-2}};
    expected = "a share such as 2% or 0.02";
  }
  const auto it = scale.find(suffix);
  if (text.empty() || end == begin || it == scale.end() || !std::isfinite(x) || !(x > 0))
    throw std::invalid_argument("expected " + expected + ", greater than zero; got \"" + raw + "\"");
  return x * it->second;
}

std::vector<Method> defaultCandidates() {
  std::vector<Method> out;
  auto add = [&](const std::string& spec) {
    for (Method& m : parseMethods(spec)) out.push_back(std::move(m));
  };
  add("a1:h=1/30|1/60|1/120|1/240");
  add("a2:m=2|4|10|20|40:h=1/30|1/60|1/120|1/240:warm=off|on");
  // Havok's three stiffnesses (soft, medium, hard) and the pyramid's kappa 0.85, tau 0.
  for (const char* algo : {"a5", "a4", "a3"})
    for (const char* kt : {"kappa=1:tau=0.6", "kappa=0.9:tau=0.3", "kappa=1.1:tau=0.9", "kappa=0.85:tau=0"})
      add(std::string(algo) + ":n=1|2|4|8:m=1|2|4:h=1/30|1/60|1/120:" + kt + ":warm=off|on");
  add("soft:n=1|2|4|8:h=1/30|1/60|1/120");
  return out;
}

double estimatedWork(const Method& m, const Scene& scene) {
  const SolverSettings s = methodSettings(m, scene);
  // Sweeps per step, weighted by what a sweep of each family costs against A5's (substep-bench,
  // docs/benchmarks.md: A3 re-formulates between sub-steps, the soft step relaxes after each);
  // A1's dense solve counted as 25 sweeps; geometry and formulation as 3.
  double sweeps = 0;
  switch (s.algorithm) {
    case Algorithm::A1: sweeps = 25; break;
    case Algorithm::A2: sweeps = s.iterations; break;
    case Algorithm::A3: sweeps = 1.4 * s.substeps * s.iterations; break;
    case Algorithm::A4: sweeps = 1.05 * s.substeps * s.iterations; break;
    case Algorithm::A5: sweeps = 1.0 * s.substeps * s.iterations; break;
    case Algorithm::Soft: sweeps = 2.0 * s.substeps * s.iterations; break;
  }
  if (m.isPeer()) sweeps = s.iterations;
  return (3 + sweeps) / s.dt;
}

namespace {

// A time in a run, as people read it: "0.00833 s", "1.5 s".
std::string timeText(double t) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g s", t);
  return buf;
}


}  // namespace


namespace {

std::string missedText(const std::string& metric, double value, double bound) { return comparisonText(metric, value, ">", bound); }

}  // namespace

FoundReference findConvergedReference(const Scene& scene, double seconds, double budget) {
  const auto start = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  // Beyond a year: no deadline (and no overflow of the clock's range).
  const auto deadline = budget < 3e7 ? start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(budget))
                                     : std::chrono::steady_clock::time_point::max();
  FoundReference f;
  // A1 solves each step's contacts and joints exactly, so it converges fastest where it can run;
  // A3 re-formulates between sub-steps and is the one that converges on scenes A1 refuses.
  for (const char* method : {"a1:h=1/480", "a1:h=1/960", "a3:n=8:m=4:h=1/480", "a3:n=8:m=4:h=1/960"}) {
    SceneReference r;
    r.kind = SceneReference::Kind::Converged;
    r.method = method;
    try {
      f.prepared.kind = r.kind;
      f.prepared.converged = convergedReference(scene, r, seconds, kTrajectoryInterval, deadline);
      f.reference = r;
      f.seconds = elapsed();
      return f;
    } catch (const ReferenceError& e) {
      f.rejected.push_back(e.what());
    } catch (const TimeBudgetSpent& e) {
      std::string why = "the time budget (" + numberText(budget) + " s) ran out after " + numberText(std::round(10 * elapsed()) / 10) +
                        " s computing a converged reference for " + scene.file + " over " + numberText(seconds) + " s: " + e.what();
      for (const std::string& no : f.rejected) why += "\n  not converged before it: " + no;
      throw TimeBudgetSpent(why + "\nGive a larger --budget, a shorter --seconds, or a target that needs no reference "
                                  "(--max-penetration, --max-joint-error, --stand)");
    }
  }
  std::string why = "no converged reference for " + scene.file + " over " + numberText(seconds) + " s:";
  for (const std::string& r : f.rejected) why += "\n  " + r;
  throw ReferenceError(why + "\nGive the scene a criteria.reference, a shorter --seconds, or a target that needs none "
                              "(--max-penetration, --max-joint-error, --stand)");
}

namespace {

// The ladder a candidate stands on: the method without h, n and m (a peer's it), the settings
// along which error falls as work rises, as parseMethods read them, so that specs written in
// another order or spelling ("a5:tau=0:kappa=1", "a5:kappa=1.0:tau=0") stand on the same one.
std::string ladderOf(const Method& m) {
  SolverOverrides rest = m.overrides;
  rest.clear(&SolverSettings::dt);
  rest.clear(&SolverSettings::substeps);
  rest.clear(&SolverSettings::iterations);
  std::string key = m.peer + "|" + rest.specText();
  for (const auto& [name, value] : m.peerOptions) key += ":" + name + "=" + numberText(value);
  return key;
}

}  // namespace

SearchOrder::SearchOrder(const std::vector<Method>& candidates, const std::vector<double>& work)
    : work_(work), given_(work.size(), false), ladderOf_(work.size(), 0) {
  for (size_t i = 0; i < work.size(); ++i) byWork_.push_back(i);
  std::stable_sort(byWork_.begin(), byWork_.end(), [&](size_t a, size_t b) { return work_[a] < work_[b]; });
  std::map<std::string, size_t> ladderIndex;
  for (size_t i : byWork_) {
    const auto [it, added] = ladderIndex.emplace(ladderOf(candidates[i]), ladders_.size());
    if (added) ladders_.emplace_back();
    ladders_[it->second].rungs.push_back(i);
    ladderOf_[i] = it->second;
  }
}

std::optional<size_t> SearchOrder::Ladder::probe() const {
  const int top = static_cast<int>(rungs.size()) - 1;
  if (lowestMet < 0) {
    // Climbing: rungs 0, 1, 3, 7, ... (each twice as far up), the top last.
    if (highestMissed >= top) return std::nullopt;
    return static_cast<size_t>(std::min(std::max(2 * highestMissed + 1, 0), top));
  }
  if (lowestMet - highestMissed <= 1) return std::nullopt;
  return static_cast<size_t>((highestMissed + lowestMet) / 2);  // bisecting
}

std::optional<size_t> SearchOrder::next(const std::function<bool(double)>& ruledOut) {
  // The cheapest candidate not yet given ...
  std::optional<size_t> frontier;
  for (size_t c : byWork_)
    if (!given_[c] && !ruledOut(work_[c])) {
      frontier = c;
      break;
    }
  if (!frontier) return std::nullopt;
  // ... unless a ladder asks for a rung less than kReach times its work: the cheapest such probe.
  std::optional<size_t> best;
  for (const Ladder& l : ladders_) {
    const std::optional<size_t> rung = l.probe();
    if (!rung) continue;
    const size_t c = l.rungs[*rung];
    if (given_[c] || ruledOut(work_[c]) || work_[c] > kReach * work_[*frontier]) continue;
    if (!best || work_[c] < work_[*best]) best = c;
  }
  const size_t c = best ? *best : *frontier;
  given_[c] = true;
  return c;
}

void SearchOrder::report(size_t candidate, bool met) {
  Ladder& l = ladders_[ladderOf_[candidate]];
  const int rung = static_cast<int>(std::find(l.rungs.begin(), l.rungs.end(), candidate) - l.rungs.begin());
  if (met) {
    if (l.lowestMet < 0 || rung < l.lowestMet) l.lowestMet = rung;
  } else if (l.lowestMet < 0 || rung < l.lowestMet) {
    l.highestMissed = std::max(l.highestMissed, rung);
  }
}

std::vector<size_t> SearchOrder::left(const std::function<bool(double)>& ruledOut) const {
  std::vector<size_t> out;
  for (size_t c : byWork_)
    if (!given_[c] && !ruledOut(work_[c])) out.push_back(c);
  return out;
}

Advice advise(const Scene& scene, const AdviseOptions& o, const std::function<void(size_t, size_t, const Candidate&)>& progress) {
  if (o.targets.empty()) throw std::invalid_argument("advise: no target (a quantity's bound, \"stand\" or \"criteria\")");
  for (const Target& t : o.targets)
    if (t.metric == "criteria" && !(scene.criteria && hasChecks(*scene.criteria)))
      throw std::invalid_argument("advise: a \"criteria\" target on " + scene.file +
                                  ", which states no criteria.pass (nor moving, stay_in, turns) to pass");
  std::vector<Method> candidates = o.candidates.empty() ? defaultCandidates() : o.candidates;
  std::vector<double> work;
  for (const Method& m : candidates) work.push_back(estimatedWork(m, scene));
  SearchOrder order(candidates, work);

  // The scene's own reference (a converged run costs) is part of the search's time.
  const auto start = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  std::optional<PreparedReference> reference = o.reference;
  if (!reference && scene.criteria && scene.criteria->reference) reference = prepareReference(scene, *scene.criteria->reference, o.seconds);
  Advice a;
  a.total = candidates.size();
  double cheapestPassWork = INFINITY;
  int passes = 0;
  // Beyond what the cheapest that met could lose to: its measured cost may be off from the
  // estimate by 1.5x once two met, 3x while one has.
  auto ruledOut = [&](double w) {
    return (passes >= 2 && w > 1.5 * cheapestPassWork) || (passes == 1 && w > 3 * cheapestPassWork);
  };
  std::vector<double> wall;  // [s] of each run tried
  for (;;) {
    if ((o.maxRuns > 0 && static_cast<int>(a.tried.size()) >= o.maxRuns) || o.budgetUsed + elapsed() >= o.timeBudget) {
      for (size_t r : order.left(ruledOut)) a.notRun.push_back(candidates[r]);
      a.budgetSpent = !a.notRun.empty();
      break;
    }
    const std::optional<size_t> next = order.next(ruledOut);
    if (!next) break;
    const size_t index = *next;
    Candidate c;
    c.method = candidates[index];
    RunSetup setup;
    setup.seconds = o.seconds;
    setup.reference = reference ? &*reference : nullptr;
    setup.stop = [&](const Metrics& m, double t) -> std::string {
      for (const Target& target : o.targets) {
        if (target.metric == "stand") {
          if (m.collapseTime) return "moved beyond the tolerance at " + timeText(*m.collapseTime);
          continue;
        }
        if (target.metric == "criteria") {
          const std::string missed = boundMissed(*scene.criteria, m);
          if (!missed.empty()) return missed + " at " + timeText(t);
          continue;
        }
        if (!growsOnly(target.metric)) continue;
        const std::optional<double> v = metricValue(m, target.metric);
        if (v && *v > target.bound) return missedText(target.metric, *v, target.bound) + " at " + timeText(t);
      }
      return "";
    };
    const auto ran = std::chrono::steady_clock::now();
    c.run = runMethod(scene, c.method, setup);
    // Judged on the whole run (or as far as it got).
    c.meets = !c.run.refused && !c.run.diverged && c.run.stoppedEarly.empty();
    c.missed = c.run.refused ? "refused: " + c.run.stopped : c.run.diverged ? c.run.stopped : c.run.stoppedEarly;
    for (const Target& target : o.targets) {
      if (target.metric == "stand") {
        if (c.run.metrics.collapseTime && c.missed.empty()) c.missed = "moved beyond the tolerance";
        c.meets = c.meets && !c.run.metrics.collapseTime;
        continue;
      }
      if (target.metric == "criteria") {
        const Verdict v = judge(scene, c.run);
        double worst = 0;
        for (const Check& k : v.checks) worst = std::max(worst, k.ratio);
        if (&target == &o.targets.front()) c.value = c.run.refused ? INFINITY : worst;
        if (v.result != Verdict::Result::Pass) {
          c.meets = false;
          if (c.missed.empty()) c.missed = v.figure;
        }
        continue;
      }
      const std::optional<double> v = metricValue(c.run.metrics, target.metric);
      if (&target == &o.targets.front()) c.value = v.value_or(INFINITY);
      if (!v || *v > target.bound) {
        c.meets = false;
        if (c.missed.empty()) c.missed = v ? missedText(target.metric, *v, target.bound) : std::string(metricLabel(target.metric)) + " not measured";
      }
    }
    // Standing: the later it moved, the closer (never: the closest of all).
    if (o.targets.front().metric == "stand") c.value = c.run.metrics.collapseTime ? -*c.run.metrics.collapseTime : -INFINITY;
    if (c.meets) {
      ++passes;
      cheapestPassWork = std::min(cheapestPassWork, work[index]);
    }
    order.report(index, c.meets);
    a.tried.push_back(std::move(c));
    wall.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - ran).count());
    if (progress) progress(a.tried.size(), candidates.size(), a.tried.back());
  }
  // The two cheapest that met, by the cost of their run ...
  for (size_t i = 0; i < a.tried.size(); ++i) {
    const Candidate& c = a.tried[i];
    if (!c.meets) continue;
    const int k = static_cast<int>(i);
    if (a.best < 0 || c.run.msPerSecond() < a.tried[static_cast<size_t>(a.best)].run.msPerSecond()) {
      a.runnerUp = a.best;
      a.best = k;
    } else if (a.runnerUp < 0 || c.run.msPerSecond() < a.tried[static_cast<size_t>(a.runnerUp)].run.msPerSecond()) {
      a.runnerUp = k;
    }
  }
  // ... timed again whole (median of the repeats, no observer stopping them) and ranked again by
  // that cost; with fewer repeats (one at least) where the budget left has no room for them all.
  for (int k : {a.best, a.runnerUp}) {
    if (k < 0 || o.repeat < 1) continue;
    Candidate& c = a.tried[static_cast<size_t>(k)];
    const double left = o.timeBudget - o.budgetUsed - elapsed(), one = wall[static_cast<size_t>(k)];
    RunSetup timed;
    timed.seconds = o.seconds;
    timed.reference = reference ? &*reference : nullptr;
    timed.repeat = std::clamp(static_cast<int>(std::floor(left / std::max(one, 1e-9))), 1, o.repeat);
    c.run = runMethod(scene, c.method, timed);
  }
  if (a.runnerUp >= 0 && a.tried[static_cast<size_t>(a.runnerUp)].run.msPerSecond() < a.tried[static_cast<size_t>(a.best)].run.msPerSecond())
    std::swap(a.best, a.runnerUp);
  a.searched = a.tried.size();
  a.seconds = elapsed();
  if (a.best < 0)
    for (size_t i = 0; i < a.tried.size(); ++i) {
      const Candidate& c = a.tried[i];
      if (c.run.refused) continue;
      if (a.closest < 0 || c.value < a.tried[static_cast<size_t>(a.closest)].value) a.closest = static_cast<int>(i);
    }
  return a;
}

}  // namespace substep::lab

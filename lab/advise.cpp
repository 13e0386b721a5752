#include "lab/advise.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>

namespace substep::lab {

std::string Target::text() const {
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
  if (m.isBullet()) sweeps = s.iterations;
  return (3 + sweeps) / s.dt;
}

namespace {

// Quantities that only grow during a run: a run can stop once one is beyond its bound.
bool growsOnly(const std::string& metric) {
  return metric == "penetration" || metric == "joint_error" || metric == "joint_angle_error" || metric == "limit_excess" ||
         metric == "displacement" || metric == "speed";
}

std::string missedText(const std::string& metric, double value, double bound) {
  return std::string(metricLabel(metric)) + " " + formatMetric(metric, value) + " > " + formatMetric(metric, bound);
}

}  // namespace

Advice advise(const Scene& scene, const AdviseOptions& o, const std::function<void(size_t, size_t, const Candidate&)>& progress) {
  std::vector<Method> candidates = o.candidates.empty() ? defaultCandidates() : o.candidates;
  std::vector<std::pair<double, size_t>> order;
  for (size_t i = 0; i < candidates.size(); ++i) order.emplace_back(estimatedWork(candidates[i], scene), i);
  std::stable_sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return a.first < b.first; });

  std::optional<PreparedReference> reference;
  if (scene.criteria && scene.criteria->reference) reference = prepareReference(scene, *scene.criteria->reference, o.seconds);
  Advice a;
  a.total = candidates.size();
  double cheapestPassWork = INFINITY;
  int passes = 0;
  for (const auto& [work, index] : order) {
    if ((passes >= 2 && work > 1.5 * cheapestPassWork) || (passes == 1 && work > 3 * cheapestPassWork)) break;
    if (static_cast<int>(a.tried.size()) >= o.budget) {
      a.budgetSpent = true;
      break;
    }
    Candidate c;
    c.method = candidates[index];
    RunSetup setup;
    setup.seconds = o.seconds;
    setup.reference = reference ? &*reference : nullptr;
    setup.stop = [&](const Metrics& m, double t) -> std::string {
      for (const Target& target : o.targets) {
        if (target.metric == "stand") {
          if (m.collapseTime) return "moved beyond the tolerance at " + numberText(*m.collapseTime) + " s";
          continue;
        }
        if (!growsOnly(target.metric)) continue;
        const std::optional<double> v = metricValue(m, target.metric);
        if (v && *v > target.bound) return missedText(target.metric, *v, target.bound) + " at " + numberText(t) + " s";
      }
      return "";
    };
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
      // Timed again, whole, with repeats: the cost that ranks it.
      RunSetup timed = setup;
      timed.stop = nullptr;
      timed.repeat = o.repeat;
      c.run = runMethod(scene, c.method, timed);
      ++passes;
      cheapestPassWork = std::min(cheapestPassWork, work);
    }
    a.tried.push_back(std::move(c));
    if (progress) progress(a.tried.size(), order.size(), a.tried.back());
  }
  a.searched = a.tried.size();
  // Rank what met the targets by measured cost per simulated second.
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
  if (a.best < 0)
    for (size_t i = 0; i < a.tried.size(); ++i) {
      const Candidate& c = a.tried[i];
      if (c.run.refused) continue;
      if (a.closest < 0 || c.value < a.tried[static_cast<size_t>(a.closest)].value) a.closest = static_cast<int>(i);
    }
  return a;
}

}  // namespace substep::lab

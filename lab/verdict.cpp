#include "lab/verdict.h"

#include <cmath>

namespace substep::lab {

const char* resultName(Verdict::Result r) {
  switch (r) {
    case Verdict::Result::Pass: return "pass";
    case Verdict::Result::Fail: return "fail";
    case Verdict::Result::Refused: return "refused";
    case Verdict::Result::NoCriteria: return "none";
  }
  return "?";
}

double checkMargin(const Check& c) {
  if (!c.ok) return NAN;
  switch (c.kind) {
    case Check::Kind::AtMost: return 1 - c.ratio;                         // ratio: value / bound
    case Check::Kind::AtLeast: return c.ratio > 0 ? 1 / c.ratio - 1 : NAN;  // ratio: bound / value
    case Check::Kind::Holds: return NAN;
  }
  return NAN;
}

Check checkAtMost(const std::string& name, std::optional<double> value, double bound) {
  Check c;
  c.kind = Check::Kind::AtMost;
  if (!value) {
    c.text = std::string(metricLabel(name)) + ": not measured in this run";
    c.ratio = INFINITY;
    return c;
  }
  c.ok = *value <= bound;
  c.ratio = bound > 0 ? *value / bound : (*value > 0 ? INFINITY : 0);
  c.text = comparisonText(name, *value, c.ok ? "<=" : ">", bound);
  return c;
}

bool growsOnly(const std::string& metric) {
  return metric == "penetration" || metric == "joint_error" || metric == "joint_angle_error" || metric == "limit_excess" ||
         metric == "displacement" || metric == "sideways" || metric == "speed";
}

std::string boundMissed(const SceneCriteria& c, const Metrics& m) {
  for (const auto& [name, bound] : c.pass) {
    const std::optional<double> v = growsOnly(name) ? metricValue(m, name) : std::nullopt;
    if (v && *v > bound) return comparisonText(name, *v, ">", bound);
  }
  return "";
}

bool hasChecks(const SceneCriteria& c) { return !c.pass.empty() || c.moving || c.stayIn || c.turns; }

Verdict judge(const Scene& scene, const RunResult& run) {
  Verdict v;
  if (run.refused) {
    v.result = Verdict::Result::Refused;
    v.figure = run.stopped;
    return v;
  }
  if (!scene.criteria) return v;
  const SceneCriteria& c = *scene.criteria;
  const Metrics& m = run.metrics;
  if (run.diverged) v.checks.push_back(Check{run.stopped.substr(0, run.stopped.find(':')), false, INFINITY});
  for (const auto& [name, bound] : c.pass) v.checks.push_back(checkAtMost(name, metricValue(m, name), bound));
  if (c.moving) {
    const double least = m.movingLeast.value_or(0);
    Check k;
    k.kind = Check::Kind::AtLeast;
    k.ok = least >= c.moving->atLeast;
    k.ratio = least > 0 ? c.moving->atLeast / least : INFINITY;
    k.text = "the sliding bodies moved at least " + formatLength(least) + (k.ok ? " >= " : " < ") + formatLength(c.moving->atLeast);
    v.checks.push_back(k);
  }
  if (c.stayIn) {
    const std::string& name = scene.model.bodies[static_cast<size_t>(c.stayIn->body)].name;
    const bool in = m.stayedIn.value_or(false);
    v.checks.push_back(Check{in ? name + " stayed inside its box" : name + " left its box (passed through)", in, in ? 0.0 : INFINITY});
  }
  if (c.turns) {
    const double most = m.turnedMost.value_or(0);
    Check k;
    k.kind = Check::Kind::AtLeast;
    k.ok = most >= c.turns->atLeast;
    k.ratio = most > 0 ? c.turns->atLeast / most : INFINITY;
    char buf[96];
    std::snprintf(buf, sizeof buf, "turned %.0f deg %s %.0f deg", most * 180 / M_PI, k.ok ? ">=" : "<", c.turns->atLeast * 180 / M_PI);
    k.text = buf;
    v.checks.push_back(k);
  }
  // A scene that states no check has no verdict, whatever became of the run.
  if (!hasChecks(c)) {
    v.checks.clear();
    return v;
  }
  v.result = Verdict::Result::Pass;
  for (size_t i = 0; i < v.checks.size(); ++i) {
    const Check& k = v.checks[i];
    if (!k.ok) {
      v.result = Verdict::Result::Fail;
      v.decisive = static_cast<int>(i);
      break;
    }
    if (v.decisive < 0 || k.ratio > v.checks[static_cast<size_t>(v.decisive)].ratio) v.decisive = static_cast<int>(i);
  }
  if (v.decisive >= 0) v.figure = v.checks[static_cast<size_t>(v.decisive)].text;
  return v;
}

}  // namespace substep::lab

#include "lab/compare.h"

#include "lab/chart.h"
#include "lab/metrics.h"
#include "lab/record.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <sstream>

namespace substep::lab {

using json = nlohmann::json;

namespace {

std::string withoutStep(std::string text) {
  const size_t h = text.find(":h=");
  if (h == std::string::npos) return text;
  const size_t next = text.find(':', h + 1);
  return text.erase(h, next == std::string::npos ? std::string::npos : next - h);
}

std::string runText(const ComparedRun& r, const std::string& metric) {
  char speed[32];
  std::snprintf(speed, sizeof speed, r.speed >= 100 ? "%.0fx" : "%.3gx", r.speed);
  return r.curve + " h=" + r.h + " (" + formatMetric(metric, r.error) + ", " + speed + ")";
}

}  // namespace

std::vector<SceneComparison> compareRuns(const std::vector<json>& rows) {
  std::vector<SceneComparison> out;
  std::map<std::string, size_t> at;
  std::map<std::string, std::set<std::string>> refusedCurves;
  for (const json& r : rows) {
    const std::string scene = r.at("scene").get<std::string>();
    if (!at.count(scene)) {
      at[scene] = out.size();
      out.push_back(SceneComparison{});
      out.back().scene = scene;
      out.back().metric = r.at("error").at("metric").get<std::string>();
    }
    SceneComparison& s = out[at[scene]];
    const std::string method = r.at("method").get<std::string>();
    if (r.value("refused", false)) {
      const std::string curve = withoutStep(method);
      if (refusedCurves[scene].insert(curve).second) s.refused.push_back(curve + ": " + r.value("stopped", std::string()));
      continue;
    }
    if (r.value("diverged", false) || !r.value("finite", true)) {
      s.diverged.push_back(method + " h=" + r.at("h").get<std::string>());
      continue;
    }
    const std::optional<double> e = recordValue(r, s.metric);
    const json& cost = r.at("cost").at("ms_per_second");
    if (!e || !std::isfinite(*e) || !cost.is_number() || !(cost.get<double>() > 0)) continue;
    ComparedRun c{method, withoutStep(method), r.at("h").get<std::string>(), 1000 / cost.get<double>(), *e};
    // The front is computed in (1 / speed, error): lower is better in both.
    s.front.push_back(c);
  }
  for (SceneComparison& s : out) {
    std::vector<ComparedRun> all = std::move(s.front);
    s.front.clear();
    if (all.empty()) continue;
    s.mostAccurate = *std::min_element(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.error < b.error; });
    s.fastest = *std::max_element(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.speed < b.speed; });
    std::vector<std::pair<double, double>> xy;
    for (const ComparedRun& c : all) xy.emplace_back(1 / c.speed, c.error);
    for (size_t i : paretoFront(xy)) s.front.push_back(all[i]);  // fastest first
    std::map<std::string, int> count;
    for (const ComparedRun& c : s.front) ++count[c.curve];
    int best = 0;
    for (const ComparedRun& c : s.front)  // fastest first: a tie goes to the faster curve
      if (count[c.curve] > best) best = count[c.curve], s.leader = c.curve;
  }
  return out;
}

std::string comparisonTable(const std::vector<SceneComparison>& scenes) {
  std::ostringstream t;
  t << "| scene | error | leads (most runs on the front) | the front, fastest first (error, real-time factor) | most accurate | "
       "diverged |\n|---|---|---|---|---|---|\n";
  for (const SceneComparison& s : scenes) {
    t << "| " << s.scene << " | " << metricLabel(s.metric) << " | " << (s.leader.empty() ? "-" : s.leader) << " | ";
    for (size_t i = 0; i < s.front.size(); ++i) t << (i ? "; " : "") << runText(s.front[i], s.metric);
    t << " | " << (s.front.empty() ? "-" : runText(s.mostAccurate, s.metric)) << " | ";
    for (size_t i = 0; i < s.diverged.size(); ++i) t << (i ? ", " : "") << s.diverged[i];
    t << (s.diverged.empty() ? "-" : "") << " |\n";
  }
  bool any = false;
  for (const SceneComparison& s : scenes)
    for (const std::string& r : s.refused) {
      if (!any) t << "\nRefused (what the method cannot model, never approximated):\n\n";
      any = true;
      std::string line = r;
      for (char& ch : line)
        if (ch == '\n') ch = ' ';
      t << "- " << s.scene << ", " << line << "\n";
    }
  return t.str();
}

}  // namespace substep::lab

// Pass or fail: a run judged by its scene's criteria (the "criteria" block of a scene file,
// physics/scene_file.h). The atlas colours its cells with these, and its expected table holds
// them.
#pragma once

#include "lab/runner.h"

#include <string>
#include <vector>

namespace substep::lab {

struct Check {
  std::string text;   // "max joint error 3.10 cm > 2.00 cm"
  bool ok = false;
  double ratio = 0;   // how close to its bound: value / bound for "at most", bound / value for "at least"
};

struct Verdict {
  enum class Result { Pass, Fail, Refused, NoCriteria };
  Result result = Result::NoCriteria;
  std::string figure;          // the check that decided: the first that failed, else the closest to failing
  std::vector<Check> checks;
};
const char* resultName(Verdict::Result r);  // "pass", "fail", "refused", "none"

// A "pass" bound of the criteria: the metric `name` at most `bound` (not ok when not measured).
Check checkAtMost(const std::string& name, std::optional<double> value, double bound);

// Refused when the method cannot run the scene; no verdict (NoCriteria) when the scene states no
// check (no criteria, or criteria without pass bounds); else pass when the run stayed finite,
// did not diverge, and met every check.
Verdict judge(const Scene& scene, const RunResult& run);

}  // namespace substep::lab

// Pass or fail: a run judged by its scene's criteria (the "criteria" block of a scene file,
// physics/scene_file.h). The atlas colours its cells with these, and its expected table holds
// them.
#pragma once

#include "lab/runner.h"

#include <string>
#include <vector>

namespace substep::lab {

struct Check {
  enum class Kind { AtMost, AtLeast, Holds };  // a bound from above, from below, or yes or no (stays in, finite)
  std::string text;   // "max joint error 3.10 cm > 2.00 cm"
  bool ok = false;
  double ratio = 0;   // how close to its bound: value / bound for "at most", bound / value for "at least"
  Kind kind = Kind::Holds;
};
// How far a check that holds is from its bound, as a share of the bound: 0.38 for 0.62 cm under
// at most 1 cm, 0.5 for 45 cm over at least 30 cm (the direction is its kind's); NAN for a yes-or-no
// check, one that failed or one not measured.
double checkMargin(const Check& c);

struct Verdict {
  enum class Result { Pass, Fail, Refused, NoCriteria };
  Result result = Result::NoCriteria;
  std::string figure;          // the check that decided: the first that failed, else the closest to failing
  int decisive = -1;           // its index in `checks` (-1: none)
  std::vector<Check> checks;
};
const char* resultName(Verdict::Result r);  // "pass", "fail", "refused", "none"

// Whether the criteria state a check to pass: a "pass" bound, moving, stay_in or turns. Criteria
// that state none (an error measure, a reference, rest bodies only) give no verdict.
bool hasChecks(const SceneCriteria& c);

// A "pass" bound of the criteria: the metric `name` at most `bound` (not ok when not measured).
Check checkAtMost(const std::string& name, std::optional<double> value, double bound);

// Metrics that only grow during a run (the largest so far): once one is beyond its bound, the
// check fails whatever the rest of the run does.
bool growsOnly(const std::string& metric);

// The first "pass" bound already missed by a metric that only grows ("max penetration 3.10 cm >
// 3.00 cm"); empty while every bound may still hold. A run may stop there: judged, it fails.
std::string boundMissed(const SceneCriteria& c, const Metrics& m);

// Refused when the method cannot run the scene; no verdict (NoCriteria) when the scene states no
// check (no criteria, or criteria without pass bounds); else pass when the run stayed finite,
// did not diverge, and met every check.
Verdict judge(const Scene& scene, const RunResult& run);

}  // namespace substep::lab

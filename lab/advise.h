// Advice: the cheapest settings that meet an accuracy target on a scene (`substep advise`).
// The search runs candidates in order of their estimated work (steps per second x sweeps per
// step, with a per-family factor), stops each run as soon as it misses the target, times the ones
// that meet it (median of repeats) and stops once the cheapest found cannot be beaten by what is
// left (docs/lab.md, "Advice").
#pragma once

#include "lab/runner.h"

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace substep::lab {

// One target: a quantity at most a bound ("max joint error <= 1 cm"), or standing for a time.
struct Target {
  std::string metric;   // criterionMetrics(), or "stand"
  double bound = 0;     // SI; for "stand" the seconds
  std::string text() const;  // "max joint error <= 1.00 cm", "stands for 60 s"
};
// "1cm", "5 mm", "0.01", "2%", "3deg", "60s": a value in SI units (metres, radians, a share,
// seconds). `unit` is what the quantity is measured in: "m", "rad", "" (a share), "s".
// Throws std::invalid_argument naming what was expected.
double parseQuantity(const std::string& text, const std::string& unit);

struct AdviseOptions {
  std::vector<Target> targets;
  double seconds = 5;           // the run's length (a "stand" target sets it)
  std::vector<Method> candidates;  // empty: defaultCandidates()
  int repeat = 3;               // timed runs of a candidate that meets the targets
  int budget = 400;             // candidates run at most
};

// The default search: A1 at four h; A2 at 2 to 40 iterations, warm or cold; A3, A4 and A5 at
// n 1 to 8, m 1 to 4, three h, Havok's three (kappa, tau) and the pyramid's (0.85, 0), warm or
// cold; the soft step at n 1 to 8 and three h.
std::vector<Method> defaultCandidates();
// Work per simulated second, the order the search runs candidates in.
double estimatedWork(const Method& m, const Scene& scene);

struct Candidate {
  Method method;
  RunResult run;
  bool meets = false;
  std::string missed;           // the first target it missed, with its figure
  double value = 0;             // the first target's quantity (its largest over the run); "stand":
                                // minus the time it moved (lower is closer, as for the others)
};

struct Advice {
  std::vector<Candidate> tried;  // in the order run
  int best = -1, runnerUp = -1;  // indices into `tried`, by measured cost per simulated second
  int closest = -1;              // none met: the candidate nearest the first target
  size_t searched = 0, total = 0;
  bool budgetSpent = false;
};

// `progress` is told each candidate tried (index, total candidates) when given.
Advice advise(const Scene& scene, const AdviseOptions& options,
              const std::function<void(size_t, size_t, const Candidate&)>& progress = {});

}  // namespace substep::lab

// Advice: the cheapest settings that meet an accuracy target on a scene (`substep advise`).
// The search runs candidates in order of their estimated work (steps per second x sweeps per
// step, with a per-family factor), stops each run as soon as it misses the target, times the ones
// that meet it (median of repeats) and stops once the cheapest found cannot be beaten by what is
// left (docs/lab.md, "Advice").
#pragma once

#include "lab/runner.h"

#include <cmath>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace substep::lab {

// One target: a quantity at most a bound ("max joint error <= 1 cm"), standing for a time, or
// passing the scene's own criteria (lab/verdict.h: every check of its "pass" block and the rest).
struct Target {
  std::string metric;   // criterionMetrics(), "stand" or "criteria"
  double bound = 0;     // SI; for "stand" the seconds; unused for "criteria"
  // "max joint error <= 1.00 cm", "stands for 60 s"; with the scene, the criteria's checks
  std::string text(const Scene* scene = nullptr) const;
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
  double timeBudget = 60;       // [s] of wall time for the search; the candidate running then ends it
  double budgetUsed = 0;        // [s] of timeBudget already spent before the search (finding a reference)
  int maxRuns = 0;              // candidates run at most; 0: no limit but the time
  std::optional<PreparedReference> reference;  // measured against this, not the scene's own
};

// A converged reference for a scene that states none (`advise --max-error` on a user's first
// scene): the first of A1 at h 1/480 and 1/960, then A3 (n 8, m 4) at h 1/480 and 1/960, whose
// run at h/2 moves the trajectory by at most 1 % of the motion. Throws ReferenceError naming
// each one tried and why it was not taken, or TimeBudgetSpent once `budget` [s] of wall time
// has gone, saying how far it got.
struct FoundReference {
  SceneReference reference;
  PreparedReference prepared;
  double seconds = 0;                 // wall time spent finding it, the rejected ones included
  std::vector<std::string> rejected;  // why each one tried before it was not taken
};
FoundReference findConvergedReference(const Scene& scene, double seconds, double budget = INFINITY);

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
                                // minus the time it moved; "criteria": the worst check's share of
                                // its bound (lower is closer, as for the others)
};

struct Advice {
  std::vector<Candidate> tried;  // in the order run
  int best = -1, runnerUp = -1;  // indices into `tried`, by measured cost per simulated second
  int closest = -1;              // none met: the candidate nearest the first target
  size_t searched = 0, total = 0;
  bool budgetSpent = false;      // stopped by the time budget or maxRuns with candidates left
  std::vector<Method> notRun;    // then: the candidates left, cheapest estimate first
  double seconds = 0;            // wall time of the search
};

// `progress` is told each candidate tried (index, total candidates) when given. Throws
// std::invalid_argument for no target, or a "criteria" target on a scene that states no checks.
Advice advise(const Scene& scene, const AdviseOptions& options,
              const std::function<void(size_t, size_t, const Candidate&)>& progress = {});

}  // namespace substep::lab

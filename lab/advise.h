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
  int repeat = 3;               // timed runs of each of the two cheapest that met (their cost is the median)
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

// The order the search runs candidates in. A ladder is one method's candidates that differ only
// in h, n and m, cheapest first: up a ladder, error mostly falls as work rises. Each ladder is
// climbed by doubling (rungs 0, 1, 3, 7, ..., the top) until a rung meets the targets, then
// bisected between the highest rung that missed and the lowest that met. The probe of least
// estimated work over all ladders goes first, while it is within kReach times the work of the
// cheapest candidate not yet given; else that candidate. So the whole space is still searched,
// cheapest first but for the probes ahead of it, which find an answer early where most ladders
// miss (the 100-level pyramid, where only the soft step stands) without running the costly tops
// of ladders that meet anyway (the 40-level pyramid); once one meets, the work it rules out is
// not run.
class SearchOrder {
 public:
  SearchOrder(const std::vector<Method>& candidates, const std::vector<double>& work);
  static constexpr double kReach = 4;
  // The next candidate (an index into `candidates`), skipping what `ruledOut` rules out by its
  // work; nullopt when none is left.
  std::optional<size_t> next(const std::function<bool(double)>& ruledOut);
  void report(size_t candidate, bool met);  // what a given candidate did
  // Not given yet and not ruled out, cheapest first.
  std::vector<size_t> left(const std::function<bool(double)>& ruledOut) const;

 private:
  struct Ladder {
    std::vector<size_t> rungs;  // candidates, cheapest first
    int highestMissed = -1;     // the highest rung that missed, below the lowest that met
    int lowestMet = -1;
    std::optional<size_t> probe() const;  // the rung to run next, if the ladder asks for one
  };
  std::vector<double> work_;
  std::vector<bool> given_;
  std::vector<size_t> ladderOf_;
  std::vector<size_t> byWork_;
  std::vector<Ladder> ladders_;
};

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

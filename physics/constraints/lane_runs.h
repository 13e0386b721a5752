// The runs in which lanes solve a sweep's manifolds without changing a bit of its numbers:
// the soft step's (soft_step.cpp) and A5's (ConstraintSet::build lays out its groups so).
#pragma once

#include "physics/constraints/contact.h"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace substep {

// A sweep's runs: the step's order of the manifolds (an uncoloured sweep's) cut into runs
// that can be solved at once without changing a bit of it. The sequential sweep gives a
// manifold each moving body's velocity as the manifold before it on that body left it: so it
// may be solved once those (its chains' previous, one a body) are, and at once with any other
// manifold ready then, since two ready manifolds share no moving body (the later would wait
// for the earlier). Each run takes the ready manifolds, those with the longest chain of
// manifolds waiting behind them first, and when there are more than a group's eight, a whole
// number of groups of them: the rest wait for the next run, so that the lanes are full (a group
// costs the same with one lane in use as with eight; docs/algorithms.md, "Lanes and runs").
// Within a run the manifolds keep the step's order.
class LaneRuns {
 public:
  // The runs of the step's manifolds (their friction definitions, in the step's order), with
  // `mass` telling which bodies move; or of the `count` manifolds `list` names, in its order (the
  // manifolds of some islands: a sweep over those alone).
  void order(const std::vector<FrictionDef>& frictions, const std::vector<BodyMass>& mass) {
    order(frictions, mass, nullptr, frictions.size());
  }
  void order(const std::vector<FrictionDef>& frictions, const std::vector<BodyMass>& mass, const int* list, size_t count);
  // In the order of the runs, each manifold's place in the list given (in frictions without one):
  // what the runs are kept for is the bodies at those places, not which manifolds they are.
  const std::vector<int>& manifolds() const { return runOrder_; }
  const std::vector<int>& starts() const { return runStart_; }     // run r: [starts[r], starts[r + 1])

  // A fill takes the manifolds in the runs' order, not in their rows' (or, formulating them,
  // their definitions') order in memory, which no hardware prefetch follows. What outgrows the
  // core's L2 cache comes from L3 or memory: kAhead manifolds on is then fetched while these are
  // filled (docs/benchmarks.md).
  static constexpr size_t kAhead = 2;
  static bool outgrowsL2(size_t bytes);

 private:
  std::vector<int> runOrder_, runStart_;
  std::vector<uint64_t> runKey_, lastRunKey_;  // each manifold's bodies, this step's and the runs'
  std::vector<int> lastOn_, after_, waiting_, chain_, ready_, waitingNext_;  // scratch
};

}  // namespace substep

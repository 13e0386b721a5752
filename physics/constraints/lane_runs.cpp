#include "physics/constraints/lane_runs.h"

#include "physics/steppers/soft_lanes.h"

#include <algorithm>
#include <cassert>
#include <unistd.h>

namespace substep {

bool LaneRuns::outgrowsL2(size_t bytes) {
  static const size_t l2 = [] {
    const long size = sysconf(_SC_LEVEL2_CACHE_SIZE);
    return size > 0 ? static_cast<size_t>(size) : size_t{1} << 20;
  }();
  return bytes > l2;
}

void LaneRuns::order(const std::vector<FrictionDef>& frictions, const std::vector<BodyMass>& mass, const int* list,
                     size_t count) {
  const auto manifold = [&](size_t k) -> const FrictionDef& { return frictions[list ? static_cast<size_t>(list[k]) : k]; };
  // The runs follow from the manifolds' bodies in the step's order and which of those move
  // (storeMoving's test): a step with the same list as the last (a settled scene, whose pairs
  // stay) keeps last step's runs.
  const auto side = [&](int body) {  // the body, or its complement when it does not move
    return static_cast<uint32_t>(mass[static_cast<size_t>(body)].invMass == 0 ? ~body : body);
  };
  runKey_.resize(count);
  for (size_t k = 0; k < count; ++k) runKey_[k] = uint64_t{side(manifold(k).a)} << 32 | side(manifold(k).b);
  // (No step's key is empty: the lanes are used only with manifolds.)
  if (runKey_ == lastRunKey_) return;
  runKey_.swap(lastRunKey_);
  // Each manifold's successors (the next on each of its moving bodies), how many predecessors
  // it waits for, and the longest chain from it to the sweep's end.
  lastOn_.assign(mass.size(), -1);
  after_.assign(2 * count, -1);
  waiting_.assign(count, 0);
  for (size_t k = 0; k < count; ++k) {
    const FrictionDef& f = manifold(k);
    // storeMoving's test: the rows' M̌⁻¹ is zero for static and sleeping bodies alone.
    int prev[2] = {-1, -1};
    for (int side = 0; side < 2; ++side) {
      const size_t body = static_cast<size_t>(side ? f.b : f.a);
      if (mass[body].invMass == 0) continue;
      prev[side] = lastOn_[body];
      if (prev[side] >= 0) {
        const size_t p = static_cast<size_t>(prev[side]);
        after_[2 * p + (manifold(p).b == static_cast<int>(body))] = static_cast<int>(k);  // the slot of p's side
      }
      lastOn_[body] = static_cast<int>(k);
    }
    waiting_[k] = (prev[0] >= 0) + (prev[1] >= 0 && prev[1] != prev[0]);
  }
  chain_.resize(count);
  for (size_t k = count; k-- > 0;) {
    int longest = 0;
    for (size_t slot = 2 * k; slot < 2 * k + 2; ++slot)
      if (after_[slot] >= 0) longest = std::max(longest, chain_[static_cast<size_t>(after_[slot])]);
    chain_[k] = longest + 1;
  }
  runOrder_.clear();
  runStart_.assign(1, 0);
  ready_.clear();
  for (size_t k = 0; k < count; ++k)
    if (waiting_[k] == 0) ready_.push_back(static_cast<int>(k));
  const size_t group = lanes::kLanes;
  while (!ready_.empty()) {
    size_t take = ready_.size();
    if (take > group) {
      // The first `take` by (longest chain, then the step's order): a selection, not a sort,
      // since the keys are distinct and what is left over is ordered again next run.
      take = take / group * group;
      std::nth_element(ready_.begin(), ready_.begin() + static_cast<std::ptrdiff_t>(take), ready_.end(), [&](int x, int y) {
        const int cx = chain_[static_cast<size_t>(x)], cy = chain_[static_cast<size_t>(y)];
        return cx != cy ? cx > cy : x < y;
      });
    }
    std::sort(ready_.begin(), ready_.begin() + static_cast<std::ptrdiff_t>(take));
    waitingNext_.assign(ready_.begin() + static_cast<std::ptrdiff_t>(take), ready_.end());
    for (size_t i = 0; i < take; ++i) {
      const size_t k = static_cast<size_t>(ready_[i]);
      runOrder_.push_back(static_cast<int>(k));
      const int s0 = after_[2 * k], s1 = after_[2 * k + 1];
      if (s0 >= 0 && --waiting_[static_cast<size_t>(s0)] == 0) waitingNext_.push_back(s0);
      if (s1 >= 0 && s1 != s0 && --waiting_[static_cast<size_t>(s1)] == 0) waitingNext_.push_back(s1);
    }
    runStart_.push_back(static_cast<int>(runOrder_.size()));
    ready_.swap(waitingNext_);
  }
  assert(runOrder_.size() == count);
}

}  // namespace substep

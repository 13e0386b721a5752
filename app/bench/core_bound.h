// What the machine's cores allow a step on N threads (substep-bench --core-check), apart from
// bench_main.cpp so that a test holds the arithmetic: each core's own step time, timed on one
// thread pinned to it, bounds a step on N threads from below. On a shared virtual machine the
// cores need not run at one speed (two vCPUs of this project's machine differed by up to 60 %),
// and then no code reaches N times one core's speed.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace substep::bench {

// The shortest step `threads` threads could take on cores whose one-thread step times are
// `alone` [s, or any one unit]: each of the fastest `threads` cores doing work in proportion to
// its speed, nothing serial and nothing lost to sharing, 1 / Σ 1/tᵢ. NaN when no core was timed.
inline double coreBound(std::vector<double> alone, int threads) {
  std::sort(alone.begin(), alone.end());
  double rate = 0;  // steps per unit time, all cores together
  for (size_t i = 0; i < alone.size() && i < static_cast<size_t>(std::max(0, threads)); ++i)
    if (alone[i] > 0) rate += 1 / alone[i];
  return rate > 0 ? 1 / rate : NAN;
}

}  // namespace substep::bench

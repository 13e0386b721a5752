// Small statistics the benchmarks share.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

namespace substep::app {

// The middle value (the mean of the two middle ones for an even count); NaN for none.
inline double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace substep::app

// How substep-bench prints numbers and ratios (bench_main.cpp), apart so that a test can hold
// the text a target is judged by to what the judgement says.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

namespace substep::bench {

inline std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

// One step time over another's: the medians' ratio and the range of the repeats' ratios.
struct Ratio {
  double median = NAN, lo = NAN, hi = NAN;
  bool valid() const { return !std::isnan(median); }
};

// "0.36x (0.35-0.37)", or "-" when there is none. Against a bound (a target's), four places
// where two would round the median onto it: 1.5996x is not "at least 1.60x", and printed as
// 1.60x beside NOT MET it would read as a contradiction.
inline std::string ratioText(const Ratio& q, double bound = NAN) {
  if (!q.valid()) return "-";
  const char* f = !std::isnan(bound) && fmt("%.2f", q.median) == fmt("%.2f", bound) ? "%.4f" : "%.2f";
  return fmt(f, q.median) + "x (" + fmt(f, q.lo) + "-" + fmt(f, q.hi) + ")";
}

}  // namespace substep::bench

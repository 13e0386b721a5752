// Side-by-side comparisons: the settings of each panel, parsed from `--compare`.
//
// Syntax: panels separated by commas, each an algorithm followed by `:key=value` settings
// (`;` also separates settings, if quoted):
//     a2:m=4,a5:n=4            a2 with 4 iterations beside a5 with 4 sub-steps
//     a1,a2:m=10:omega=1.3,a5:n=8:m=2:kappa=1.1:tau=0.9
// Keys: n (substeps), m (iterations: A2's cap, A3-A5's micro-iterations), kappa, tau, omega,
// dt (or h), tolerance, slop, preset (e.g. 4-medium), warm (on/off), block (on/off), split (on/off).
#pragma once

#include "physics/settings.h"

#include <string>
#include <vector>

namespace substep::render {

struct CompareSpec {
  std::string text;            // as written, e.g. "a5:n=4"
  SolverOverrides overrides;   // the algorithm and the settings it names
};

// Two to four panels. Throws std::invalid_argument naming the bad part and what is expected.
std::vector<CompareSpec> parseCompareSpecs(const std::string& s);

}  // namespace substep::render

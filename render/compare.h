// Side-by-side comparisons: the settings of each panel, parsed from `--compare`.
//
// Syntax: method specs (physics/settings.h) separated by commas, one panel each:
//     a2:m=4,a5:n=4            a2 with 4 iterations beside a5 with 4 sub-steps
//     a1,a2:m=10:omega=1.3,a5:n=8:m=2:kappa=1.1:tau=0.9
//     a5:n=2|4                 a5 at 2 and at 4 sub-steps (a value list: one panel per value)
// Keys and ranges are the solver settings' table (settingTable()).
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

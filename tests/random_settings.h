// Settings drawn at random from the schema (physics/settings.h), for tests that hold two ways of
// stepping to the same numbers under any settings, not only the chosen ones: every setting the
// algorithm reads, flags and choices anywhere, numbers at 0.5, 1 or 1.5 times the algorithm's
// default where the range allows.
#pragma once

#include "physics/settings.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <string>

namespace substep {

struct DrawnSettings {
  SolverOverrides overrides;  // the algorithm and every drawn setting
  std::string text;           // "substeps=4 kappa=0.85 ...", for a failure's message
};

// The settings `a` reads but those in `left` (and the algorithm) drawn; those in `mostlyOn` are on
// in two draws of three (so that a path they open is taken often).
inline DrawnSettings drawSettings(Algorithm a, std::mt19937_64& random, const std::set<std::string>& left,
                                  const std::set<std::string>& mostlyOn = {}) {
  const auto next = [&](size_t n) { return std::uniform_int_distribution<size_t>(0, n - 1)(random); };
  DrawnSettings out;
  out.overrides.set(&SolverSettings::algorithm, a);
  for (const SettingSpec& s : settingTable()) {
    if (!s.resolved() || !s.takes.has(a) || std::string(s.key) == "algorithm" || left.count(s.key)) continue;
    const double d = s.defaultFor(a);
    double v = d;
    switch (s.kind) {
      case SettingKind::Flag: v = static_cast<double>(next(2)); break;
      case SettingKind::Choice: v = static_cast<double>(next(s.choices.size())); break;
      case SettingKind::Integer: v = std::max(s.range.lo, std::round(d * (0.5 + 0.5 * static_cast<double>(next(3))))); break;
      case SettingKind::Real: v = d * (0.5 + 0.5 * static_cast<double>(next(3))); break;
    }
    if ((s.kind == SettingKind::Integer || s.kind == SettingKind::Real) && !s.range.contains(v)) v = d;
    if (mostlyOn.count(s.key) && next(3) > 0) v = 1;
    out.overrides.set(s, v);
    out.text += std::string(out.text.empty() ? "" : " ") + s.key + "=" + s.text(v);
  }
  return out;
}

}  // namespace substep

#include "render/compare.h"

#include <cmath>
#include <stdexcept>

namespace substep::render {

namespace {

std::vector<std::string> split(const std::string& s, const std::string& seps) {
  std::vector<std::string> out(1);
  for (char c : s) {
    if (seps.find(c) != std::string::npos)
      out.emplace_back();
    else
      out.back() += c;
  }
  return out;
}

std::string trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t"), b = s.find_last_not_of(" \t");
  return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}

}  // namespace

std::vector<CompareSpec> parseCompareSpecs(const std::string& s) {
  const std::string usage = " (expected e.g. --compare a2:m=4,a5:n=4)";
  std::vector<CompareSpec> specs;
  for (const std::string& rawPanel : split(s, ",")) {
    const std::string panel = trim(rawPanel);
    if (panel.empty()) throw std::invalid_argument("--compare: an empty panel in \"" + s + "\"" + usage);
    const std::vector<std::string> parts = split(panel, ":;");
    CompareSpec spec;
    spec.text = panel;
    const std::string algo = trim(parts[0]);
    spec.overrides.algorithm = parseAlgorithm(algo);
    if (!spec.overrides.algorithm)
      throw std::invalid_argument("--compare \"" + panel + "\": unknown algorithm \"" + algo +
                                  "\"; each panel starts with one of a1, a2, a3, a4, a5" + usage);
    for (size_t i = 1; i < parts.size(); ++i) {
      const std::string kv = trim(parts[i]);
      const size_t eq = kv.find('=');
      if (eq == std::string::npos || eq == 0 || eq + 1 == kv.size())
        throw std::invalid_argument("--compare \"" + panel + "\": expected key=value, got \"" + kv + "\"" + usage);
      const std::string key = trim(kv.substr(0, eq)), value = trim(kv.substr(eq + 1));
      auto bad = [&](const std::string& expected) {
        return std::invalid_argument("--compare \"" + panel + "\": " + key + ": expected " + expected + ", got \"" +
                                     value + "\"");
      };
      auto number = [&](double lo, double hi, const std::string& range) {
        size_t used = 0;
        double v;
        try {
          v = std::stod(value, &used);
        } catch (const std::exception&) {
          throw bad("a number " + range);
        }
        if (used != value.size() || !std::isfinite(v) || v < lo || v > hi) throw bad("a number " + range);
        return v;
      };
      auto integer = [&](int lo, int hi) {
        size_t used = 0;
        long v;
        const std::string range = "from " + std::to_string(lo) + " to " + std::to_string(hi);
        try {
          v = std::stol(value, &used);
        } catch (const std::exception&) {
          throw bad("a whole number " + range);
        }
        if (used != value.size() || v < lo || v > hi) throw bad("a whole number " + range);
        return static_cast<int>(v);
      };
      auto flag = [&]() {
        if (value == "on" || value == "1" || value == "true" || value == "yes") return true;
        if (value == "off" || value == "0" || value == "false" || value == "no") return false;
        throw bad("on or off");
      };
      SolverOverrides& o = spec.overrides;
      if (key == "n" || key == "substeps") o.substeps = integer(1, 1000);
      else if (key == "m" || key == "iterations") o.iterations = integer(1, 100000);
      else if (key == "kappa" || key == "κ") o.kappa = number(1e-6, 10, "in (0, 10]");
      else if (key == "tau" || key == "τ") o.tau = number(0, 10, "in [0, 10]");
      else if (key == "omega" || key == "ω") o.omega = number(1e-6, 1.999999, "in (0, 2)");
      else if (key == "dt" || key == "h") o.dt = number(1e-6, 1, "in [1e-6, 1] s");
      else if (key == "tolerance" || key == "tol") o.tolerance = number(0, 1e6, ">= 0");
      else if (key == "slop") o.slop = number(0, 1, "in [0, 1] m");
      else if (key == "preset") o.preset = value;
      else if (key == "warm" || key == "warm_start") o.warmStart = flag();
      else if (key == "block" || key == "block_solve") o.blockSolve = flag();
      else if (key == "split" || key == "split_impulse") o.splitImpulse = flag();
      else
        throw std::invalid_argument("--compare \"" + panel + "\": unknown key \"" + key +
                                    "\" (keys: n, m, kappa, tau, omega, dt, tolerance, slop, preset, warm, block, split)");
    }
    specs.push_back(spec);
  }
  if (specs.size() < 2 || specs.size() > 4)
    throw std::invalid_argument("--compare: expected 2 to 4 panels separated by commas, got " +
                                std::to_string(specs.size()) + usage);
  return specs;
}

}  // namespace substep::render

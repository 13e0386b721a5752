#include "physics/settings.h"

#include <cmath>
#include <stdexcept>

namespace substep {

const char* algorithmName(Algorithm a) {
  switch (a) {
    case Algorithm::A1: return "a1";
    case Algorithm::A2: return "a2";
    case Algorithm::A3: return "a3";
    case Algorithm::A4: return "a4";
    case Algorithm::A5: return "a5";
  }
  return "?";
}

const char* algorithmTitle(Algorithm a) {
  switch (a) {
    case Algorithm::A1: return "essential stepping, direct MLCP";
    case Algorithm::A2: return "essential stepping, iterative (PSOR)";
    case Algorithm::A3: return "Havok stepping, conceptual";
    case Algorithm::A4: return "Havok stepping, approximative";
    case Algorithm::A5: return "Havok stepping, actual";
  }
  return "?";
}

std::optional<Algorithm> parseAlgorithm(const std::string& s) {
  if (s == "a1") return Algorithm::A1;
  if (s == "a2") return Algorithm::A2;
  if (s == "a3") return Algorithm::A3;
  if (s == "a4") return Algorithm::A4;
  if (s == "a5") return Algorithm::A5;
  return std::nullopt;
}

bool subSteps(Algorithm a) { return a == Algorithm::A3 || a == Algorithm::A4 || a == Algorithm::A5; }

SolverOverrides SolverOverrides::merged(const SolverOverrides& later) const {
  SolverOverrides r = *this;
  auto take = [](auto& dst, const auto& src) {
    if (src) dst = src;
  };
  take(r.algorithm, later.algorithm);
  take(r.dt, later.dt);
  take(r.substeps, later.substeps);
  take(r.iterations, later.iterations);
  take(r.omega, later.omega);
  take(r.tolerance, later.tolerance);
  take(r.kappa, later.kappa);
  take(r.tau, later.tau);
  take(r.slop, later.slop);
  take(r.warmStart, later.warmStart);
  take(r.blockSolve, later.blockSolve);
  take(r.splitImpulse, later.splitImpulse);
  take(r.preset, later.preset);
  return r;
}

SolverOverrides SolverOverrides::withCommandLine(const SolverOverrides& commandLine) const {
  SolverOverrides scene = *this;
  if (commandLine.preset) {  // the preset replaces what it sets, where the scene set it
    scene.substeps.reset();
    scene.iterations.reset();
    scene.kappa.reset();
    scene.tau.reset();
  }
  return scene.merged(commandLine);
}

namespace {

[[noreturn]] void bad(const std::string& field, const std::string& what) {
  throw std::invalid_argument(field + ": " + what);
}

// Havok's presets (../shared/notes/anchors.md): 2, 4 or 8 sub-steps, soft/medium/hard.
void applyPreset(const std::string& name, SolverSettings& s) {
  const auto dash = name.find('-');
  const std::string count = name.substr(0, dash);
  const std::string kind = dash == std::string::npos ? "" : name.substr(dash + 1);
  if ((count != "2" && count != "4" && count != "8") || (kind != "soft" && kind != "medium" && kind != "hard"))
    bad("preset", "expected one of 2-soft, 2-medium, 2-hard, 4-soft, 4-medium, 4-hard, 8-soft, 8-medium, 8-hard; got \"" +
                      name + "\"");
  s.substeps = std::stoi(count);
  if (kind == "soft") { s.tau = 0.3; s.kappa = 0.9; }
  if (kind == "medium") { s.tau = 0.6; s.kappa = 1.0; }
  if (kind == "hard") { s.tau = 0.9; s.kappa = 1.1; }
  s.iterations = 1;
}

}  // namespace

SolverSettings resolve(const SolverOverrides& o) {
  SolverSettings s;
  s.algorithm = o.algorithm.value_or(Algorithm::A2);
  const bool sub = subSteps(s.algorithm);
  if (sub) {
    // Havok's defaults: 4 sub-steps, 1 micro-iteration, medium stiffness, stable constraints as blocks.
    s.substeps = 4;
    s.iterations = 1;
    s.tau = 0.6;
    s.kappa = 1.0;
    s.blockSolve = true;
  } else {
    s.substeps = 1;
    s.iterations = 10;
    s.tau = 1.0;
    s.kappa = 1.0;
    s.blockSolve = false;
  }
  if (o.preset) {
    if (!sub) bad("preset", std::string("presets set sub-steps, κ and τ, which ") + algorithmName(s.algorithm) +
                                " does not use; choose --algo a3, a4 or a5");
    applyPreset(*o.preset, s);
  }
  if (o.dt) s.dt = *o.dt;
  if (o.substeps) {
    if (sub) s.substeps = *o.substeps;
  }
  if (o.iterations) s.iterations = *o.iterations;
  if (o.omega) s.omega = *o.omega;
  if (o.tolerance) s.tolerance = *o.tolerance;
  if (o.kappa && sub) s.kappa = *o.kappa;
  if (o.tau && sub) s.tau = *o.tau;
  if (o.slop) s.slop = *o.slop;
  if (o.warmStart) s.warmStart = *o.warmStart;
  if (o.blockSolve) s.blockSolve = *o.blockSolve;
  if (o.splitImpulse) s.splitImpulse = *o.splitImpulse;

  if (!(s.dt > 0 && s.dt <= 1)) bad("dt", "expected a time step in (0, 1] s, got " + std::to_string(s.dt));
  if (s.substeps < 1 || s.substeps > 1000) bad("substeps", "expected 1 to 1000, got " + std::to_string(s.substeps));
  if (s.iterations < 1 || s.iterations > 100000)
    bad("iterations", "expected 1 to 100000, got " + std::to_string(s.iterations));
  if (!(s.omega > 0 && s.omega < 2)) bad("omega", "expected 0 < ω < 2 (PSOR converges only there), got " + std::to_string(s.omega));
  if (!(s.tolerance >= 0)) bad("tolerance", "expected a number >= 0");
  if (!(s.kappa > 0 && std::isfinite(s.kappa))) bad("kappa", "expected κ > 0, got " + std::to_string(s.kappa));
  if (!(s.tau >= 0 && std::isfinite(s.tau))) bad("tau", "expected τ >= 0, got " + std::to_string(s.tau));
  if (!(s.slop >= 0 && std::isfinite(s.slop))) bad("slop", "expected a length >= 0 m");
  return s;
}

}  // namespace substep

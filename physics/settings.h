// Solver settings: which of the report's algorithms steps the world, and its parameters.
#pragma once

#include <optional>
#include <string>

namespace substep {

// The report's Algorithms 1 to 5 (section IV, listings in section VI).
enum class Algorithm { A1 = 1, A2, A3, A4, A5 };
const char* algorithmName(Algorithm a);       // "a1" .. "a5"
const char* algorithmTitle(Algorithm a);      // "essential, direct" ...
std::optional<Algorithm> parseAlgorithm(const std::string& s);
bool subSteps(Algorithm a);                   // A3, A4, A5

struct SolverSettings {
  Algorithm algorithm = Algorithm::A2;
  double dt = 1.0 / 60.0;        // h [s]
  int substeps = 1;              // n: sub-steps per step (A3-A5; A1/A2 use 1)
  int iterations = 10;           // A2: iteration cap; A3-A5: micro-iterations m per sub-step
  double omega = 1.0;            // A2: over-relaxation ω of PSOR
  double tolerance = 1e-6;       // A2: stop when no row changed its velocity by more [m/s]
  double kappa = 1.0;            // κ (A3-A5)
  double tau = 0.6;              // τ (A3-A5)
  bool warmStart = false;        // start each step from the previous step's impulses
  bool splitImpulse = false;     // correct contact penetration apart from the velocity solve
  bool blockSolve = false;       // solve 'stable' (unbounded) constraints as blocks (IV.2.2 item 2)
  double slop = 0.001;           // allowed penetration: the report's hi [m]
  int directMaxRows = 1500;      // A1: largest MLCP it forms densely (rows)
};

// Settings as a scene file or a command line gives them: every field optional.
struct SolverOverrides {
  std::optional<Algorithm> algorithm;
  std::optional<double> dt;
  std::optional<int> substeps;
  std::optional<int> iterations;
  std::optional<double> omega, tolerance, kappa, tau, slop;
  std::optional<bool> warmStart, blockSolve, splitImpulse;
  std::optional<std::string> preset;   // Havok's presets, e.g. "4-medium"

  // Later values win, field by field: commandLine.merged(comparePanel).
  SolverOverrides merged(const SolverOverrides& later) const;
  // A scene file's settings under the command line's: as merged(), except that a preset on the
  // command line also replaces the scene's n, m, κ and τ (what a preset sets), so that
  // `--preset 4-medium` means Havok's medium preset on any scene. Values given on the command line
  // next to the preset still win over it (resolve() applies them after the preset).
  SolverOverrides withCommandLine(const SolverOverrides& commandLine) const;
};

// Fills what the overrides leave open with the algorithm's defaults: A1/A2 as the report has
// them (ω 1, 10 iterations, rows one by one), A3-A5 with Havok's (n 4, m 1, τ 0.6, κ 1, blocks).
// Throws std::invalid_argument with a message naming the field when a value is out of range.
SolverSettings resolve(const SolverOverrides& o);

}  // namespace substep

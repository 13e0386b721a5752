// Solver settings: which of the report's algorithms steps the world, and its parameters.
// Every setting is one row of settingTable(): its key in scene files and method specs, its
// command-line option, its range and its help. Scene files, the command line, `--compare` and the
// lab's sweeps all read settings through that table, so a range is stated once.
#pragma once

#include "physics/limits.h"

#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace substep {

// The report's Algorithms 1 to 5 (section IV, listings in section VI).
// Soft is not the report's: Box2D v3's soft step in 3D, an extension to compare against
// (physics/steppers/soft_step.cpp, docs/algorithms.md "The soft step").
enum class Algorithm { A1 = 1, A2, A3, A4, A5, Soft };
const char* algorithmName(Algorithm a);       // "a1" .. "a5", "soft"
const char* algorithmTitle(Algorithm a);      // "essential, direct" ...
std::optional<Algorithm> parseAlgorithm(const std::string& s);
bool subSteps(Algorithm a);                   // A3, A4, A5, Soft: they take n
bool havokScaled(Algorithm a);                // A3, A4, A5: they take κ and τ

// The gyroscopic term of Euler's equation I ω̇ + ω × Iω = 0, which the report's ext leaves out.
enum class Gyroscopic {
  None,      // the report's: v̌ constant in free flight (keeps ½ v̌ᵀIv̌, no precession)
  Explicit,  // ω += -h I⁻¹(ω × Iω): gains energy every step
  Implicit,  // one Newton step on I(ω' - ω) + h ω' × Iω' = 0 in the body frame (Catto, GDC 2015)
};

// Which joint Jacobians A5 recomputes between sub-steps (IV.4.1).
enum class JacobianRefresh {
  Joints,  // every joint's, from the coordinates stepped by the summed rotation (an extension)
  Stable,  // the report's: only 'stable' rows', while micro-iterating, next-frame predicted
};

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
  bool contactBlocks = false;    // solve a manifold's normal rows as one small LCP (an extension)
  double slop = 0.001;           // allowed penetration: the report's hi [m]
  // Extensions on by default, each with the report's literal behaviour a switch away.
  bool motorUnscaled = true;     // motors solved with κ = τ = 1 (off: κ, τ as on every row)
  bool frictionExempt = true;    // friction rows keep β = 0 under A4/A5's bias update (off: updated)
  bool speculative = true;       // points within a margin before touching, closing at full speed
  bool restitution = true;       // bodies' restitution applied after the velocity solve
  bool islands = true;           // a5: solve island by island (the same numbers as all at once)
  double restitutionThreshold = 1.0;  // approach speeds below this do not bounce [m/s]
  JacobianRefresh jacobians = JacobianRefresh::Joints;  // A5 (IV.4.1)
  Gyroscopic gyroscopic = Gyroscopic::None;             // the report's: none
  // The soft step (Box2D v3): softness of contacts and joints, push-out cap.
  double contactHertz = 30;      // [Hz]
  double contactDamping = 10;    // damping ratio ζ
  double jointHertz = 60;        // [Hz]
  double jointDamping = 2;       // damping ratio ζ
  double pushOut = 3;            // largest speed a soft contact pushes penetrating bodies apart [m/s]
  int directMaxRows = 1500;      // A1: largest MLCP it forms densely (rows)
  double directWorkBudget = 2e10;  // A1: floating-point operations per step (mlcp_direct.h), about 3 s here
};

// Settings as a scene file or a command line gives them: every field optional.
struct SolverOverrides {
  std::optional<Algorithm> algorithm;
  std::optional<double> dt;
  std::optional<int> substeps;
  std::optional<int> iterations;
  std::optional<double> omega, tolerance, kappa, tau, slop;
  std::optional<bool> warmStart, blockSolve, splitImpulse, contactBlocks;
  std::optional<bool> motorUnscaled, frictionExempt, speculative, restitution, islands;
  std::optional<double> restitutionThreshold;
  std::optional<std::string> jacobians;  // "joints" or "stable"
  std::optional<std::string> gyroscopic;  // "none", "explicit", "implicit"
  std::optional<double> contactHertz, contactDamping, jointHertz, jointDamping, pushOut;
  std::optional<std::string> preset;   // Havok's presets, e.g. "4-medium"

  // Later values win, field by field: commandLine.merged(comparePanel).
  SolverOverrides merged(const SolverOverrides& later) const;
  // A scene file's settings under the command line's: as merged(), except that a preset on the
  // command line also replaces the scene's n, m, κ and τ (what a preset sets), so that
  // `--preset 4-medium` means Havok's medium preset on any scene. Values given on the command line
  // next to the preset still win over it (resolve() applies them after the preset).
  SolverOverrides withCommandLine(const SolverOverrides& commandLine) const;
  bool empty() const;
};

// --- the table -------------------------------------------------------------------------------

enum class SettingKind { Integer, Real, Flag, Choice };

struct SettingSpec {
  const char* key;      // scene files' "solver" block and method specs: "substeps"
  const char* alias;    // method specs' short form: "n" ("" if none)
  const char* flag;     // command line without dashes: "substeps" (flags also get "no-" + flag)
  SettingKind kind;
  Range range;          // Integer, Real
  std::vector<std::string> choices;  // Choice
  const char* help;     // one line, for --help and docs
  std::variant<std::optional<Algorithm> SolverOverrides::*, std::optional<int> SolverOverrides::*,
               std::optional<double> SolverOverrides::*, std::optional<bool> SolverOverrides::*,
               std::optional<std::string> SolverOverrides::*>
      field;

  // "an integer in [1, 1000]", "a number in (0, 2)", "on or off", "one of a1, a2, ...".
  std::string expected() const;
  bool isSet(const SolverOverrides& o) const;
  std::string valueText(const SolverOverrides& o) const;  // "" if unset
  void copy(const SolverOverrides& from, SolverOverrides& to) const;
  void clear(SolverOverrides& o) const;
  // Setting a value checks it against the range or the choices; the message of the
  // std::invalid_argument thrown is "expected <expected()>, got <value>".
  void setNumber(SolverOverrides& o, double x) const;        // Integer, Real
  void setFlag(SolverOverrides& o, bool b) const;            // Flag
  void setText(SolverOverrides& o, const std::string& text) const;  // any kind, parsed
};

const std::vector<SettingSpec>& settingTable();
// By key, alias or command-line flag name; null if none.
const SettingSpec* findSetting(const std::string& name);
// "n, m, kappa, ..." for messages.
std::string settingKeys();

// --- method specs ----------------------------------------------------------------------------
// An algorithm and settings, as `--compare` and the lab write them:
//     a5:n=4:kappa=0.85          a2:m=10:omega=1.3:warm=on
// Settings after the algorithm are key=value (keys or aliases of the table), separated by ':'
// (or ';'). A value may be a list a|b|c: the spec then names the grid of every combination.
// Real values may be written as fractions: h=1/120.
//
// A spec may also name a peer engine instead of an algorithm: `bullet:it=10:h=1/60` is Bullet 3
// stepping the same scene (the lab's peer, lab/bullet_peer.h), with the settings it maps: h (dt),
// it (or m, iterations: its solver iterations) and gyro (its gyroscopic term). The peer itself is
// the lab's business; the spec language is the same for every method.
struct MethodSpec {
  std::string text;            // as written (one combination: the lists resolved)
  SolverOverrides overrides;   // the algorithm and the settings it names (a peer: no algorithm)
  std::string peer;            // "" for substep's algorithms, "bullet" for the Bullet peer
};
// The peer engines a spec may name, and the setting keys each takes.
inline constexpr const char* kBulletPeer = "bullet";
// One spec; with value lists, every combination in order (the last key varies fastest).
// Throws std::invalid_argument naming the spec, the key and what was expected.
std::vector<MethodSpec> expandMethodSpec(const std::string& spec);
// A comma-separated list of specs, each expanded.
std::vector<MethodSpec> parseMethodSpecs(const std::string& list);

// Fills what the overrides leave open with the algorithm's defaults: A1/A2 as the report has
// them (ω 1, 10 iterations, rows one by one), A3-A5 with Havok's (n 4, m 1, τ 0.6, κ 1, blocks).
// Throws std::invalid_argument with a message naming the field when a value is out of range.
SolverSettings resolve(const SolverOverrides& o);

}  // namespace substep

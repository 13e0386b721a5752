// Solver settings: which of the report's algorithms steps the world, and its parameters.
//
// One schema describes every setting once (settingTable(), in settings.cpp): its key in scene
// files, method specs and JSON, its alias and command-line flag, its type and range, its default
// for each algorithm, which algorithms read it, whether it is one of the report's or an extension,
// how the page shows it, and its help. Each row points at the field of SolverSettings it sets, so
// that every reader and writer is a loop over the table: the command line and its --no- forms,
// method specs and grids, the scene's "solver" block, JSON out and in (settings_json.h), the
// settings lines, the server's /api/methods and the page's controls. Adding a setting is a field
// of SolverSettings, one row, and the code that uses it.
#pragma once

#include "physics/limits.h"

#include <array>
#include <bitset>
#include <initializer_list>
#include <map>
#include <optional>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

namespace substep {

// The report's Algorithms 1 to 5 (section IV, listings in section VI).
// Soft is not the report's: Box2D v3's soft step in 3D, an extension to compare against
// (physics/steppers/soft_step.cpp, docs/algorithms.md "The soft step").
enum class Algorithm { A1 = 1, A2, A3, A4, A5, Soft };
inline constexpr int kAlgorithmCount = 6;
inline constexpr std::array<Algorithm, kAlgorithmCount> kAlgorithms = {Algorithm::A1, Algorithm::A2, Algorithm::A3,
                                                                      Algorithm::A4, Algorithm::A5, Algorithm::Soft};
const char* algorithmName(Algorithm a);       // "a1" .. "a5", "soft"
const char* algorithmTitle(Algorithm a);      // "essential stepping, direct MLCP" ...
std::optional<Algorithm> parseAlgorithm(const std::string& s);
bool subSteps(Algorithm a);                   // A3, A4, A5, Soft: they take n
bool havokScaled(Algorithm a);                // A3, A4, A5: they take κ and τ

// A set of algorithms: which read a setting.
class AlgorithmSet {
 public:
  constexpr AlgorithmSet() = default;
  constexpr AlgorithmSet(std::initializer_list<Algorithm> list) {
    for (Algorithm a : list) bits_ |= bit(a);
  }
  constexpr bool has(Algorithm a) const { return (bits_ & bit(a)) != 0; }
  constexpr bool all() const { return bits_ == 0x3f; }
  std::string text() const;  // "a3, a4, a5"

 private:
  static constexpr unsigned bit(Algorithm a) { return 1u << (static_cast<int>(a) - 1); }
  unsigned bits_ = 0;
};

// The gyroscopic term of Euler's equation I ω̇ + ω × Iω = 0, which the report's ext leaves out.
enum class Gyroscopic {
  None,      // the report's: v̌ constant in free flight (keeps ½ v̌ᵀIv̌, no precession)
  Explicit,  // ω += -h I⁻¹(ω × Iω): gains energy every step
  Implicit,  // one Newton step on I(ω' - ω) + h ω' × Iω' = 0 in the body frame (Catto, GDC 2015)
};

// Which joints A5 re-formulates between sub-steps (IV.4.1).
enum class JacobianRefresh {
  EveryJoint,  // every joint's J̌, from the coordinates stepped by the summed rotation (an extension)
  Stable,      // the report's: only 'stable' rows', while micro-iterating, next-frame predicted
};

// The order in which an iterative solver sweeps the contact rows (the report leaves it open).
enum class ContactOrder {
  Split,     // every manifold's friction rows, then every normal row (cold: normals first): the
             // normal impulses bounding friction exist when friction is solved
  Manifold,  // each manifold's normal rows, then its friction rows: Box2D's and Box3D's order
};

// The frame a contact's rows are formulated in (docs/algorithms.md, "The soft step at scale").
enum class ContactFrame {
  Bodies,  // the normal and the arms follow the bodies: J̌ from the coordinates of each step (s2)
  World,   // the normal and the arms stay where the narrowphase found them in the world until it
           // runs again for the pair; the separation follows the bodies (Box3D's contact recycling)
};

// The settings a run uses, every one resolved (resolve()). A default-constructed one holds A2's
// defaults from the schema. Each field is one row of the schema; ranges, defaults and help are
// there, not here.
struct SolverSettings {
  SolverSettings();

  Algorithm algorithm;
  double dt;                      // h [s]
  int substeps;                   // n: sub-steps per step
  int iterations;                 // A2: iteration cap; A3-A5: micro-iterations m; soft: sweeps
  double omega;                   // A2: over-relaxation ω of PSOR
  double tolerance;               // A2: stop when no row's velocity changed more [m/s]
  double kappa;                   // κ (A3-A5)
  double tau;                     // τ (A3-A5)
  double slop;                    // allowed penetration, the report's hi [m]
  bool warmStart;                 // start each (sub-)step from the previous one's impulses
  bool blockSolve;                // 'stable' (unbounded) joint rows solved as blocks (IV.2.2 item 2)
  bool contactBlocks;             // a manifold's normal rows solved as one small LCP
  bool splitImpulse;              // contact penetration corrected apart from the velocity solve
  bool motorUnscaled;             // motors solved with κ = τ = 1
  bool frictionExempt;            // friction rows keep β = 0 under A4/A5's bias update
  bool speculative;               // points within a margin before touching, closing at full speed
  bool restitution;               // bodies' restitution applied after the velocity solve
  double restitutionThreshold;    // approach speeds below this do not bounce [m/s]
  bool islands;                   // A5: island by island (the same numbers as all at once)
  JacobianRefresh jacobians;      // A5 (IV.4.1)
  Gyroscopic gyroscopic;
  ContactOrder contactOrder;      // how iterative solvers order contact rows
  ContactFrame contactFrame;      // what the contact rows' normal and arms follow
  double contactHertz;            // soft: contact stiffness [Hz]
  double contactDamping;          // soft: damping ratio ζ
  double jointHertz;              // soft: joint stiffness [Hz]
  double jointDamping;            // soft: damping ratio ζ
  double pushOut;                 // soft: largest push-out speed [m/s]
  bool sleep;                      // islands at rest for half a second stop stepping until woken
  int threads;                    // threads a step runs on (results do not depend on it)
  bool colours;                   // soft: contacts solved colour by colour, the colours over the threads
  bool lanes;                     // soft: contacts solved eight at a time in SIMD lanes (same numbers)
  int directMaxRows;              // A1: largest MLCP it forms densely [rows]
  double directWorkBudget;        // A1: floating-point operations per step (mlcp_direct.h)
};

// --- the schema ------------------------------------------------------------------------------

enum class SettingKind { Integer, Real, Flag, Choice };
enum class SettingOrigin {
  Report,     // one of the report's parameters (n, m, κ, τ, h, ...)
  Extension,  // beyond the report (warm starting, speculative contacts, the soft step, ...)
  Limit,      // substep's own resource limits (A1's size and work budget)
};
const char* originName(SettingOrigin o);  // "report", "extension", "limit"

// The setting's field in SolverSettings; none for a setting that only sets others (a preset).
using SettingField = std::variant<std::monostate, Algorithm SolverSettings::*, int SolverSettings::*,
                                  double SolverSettings::*, bool SolverSettings::*,
                                  JacobianRefresh SolverSettings::*, Gyroscopic SolverSettings::*,
                                  ContactOrder SolverSettings::*, ContactFrame SolverSettings::*>;

// How the page shows a setting: among the main controls, and a slider's useful part of the range.
struct SettingControl {
  bool main = false;
  const char* label = "";   // "n (sub-steps)"; "" : the key
  double min = 0, max = 0, step = 0;
};

// Every value of a setting is held as a double: numbers as they are, flags 0 or 1, choices the
// index of their name in `choices`.
struct SettingSpec {
  const char* key;        // scene files, method specs and JSON: "substeps"
  const char* alias;      // method specs' short form: "n" ("" if none)
  const char* flag;       // command line without dashes: "substeps" (flags also get "no-" + flag)
  SettingKind kind;
  Range range;            // Integer, Real
  std::vector<std::string> choices;  // Choice
  AlgorithmSet takes;     // the algorithms that read it
  SettingOrigin origin;
  // In settings lines: a number "κ=0.85" from "κ=%s"; a flag its word when on ("warm"); a
  // choice "jacobians=%s"; "" for a setting no line shows (threads: it changes no number). Brief lines show a setting for these algorithms always, else only
  // when it differs from the algorithm's default.
  const char* line;
  AlgorithmSet brief;
  const char* help;       // one line, for --help, /api/methods and docs
  SettingField field;
  std::array<double, kAlgorithmCount> defaults;  // for a1 .. a5, soft
  SettingControl control;
  size_t index = 0;       // its place in the table

  bool resolved() const { return field.index() != 0; }  // false: it only sets others
  double defaultFor(Algorithm a) const { return defaults[static_cast<size_t>(a) - 1]; }
  // "an integer in [1, 1000]", "a number in (0, 2)", "on or off", "one of a1, a2, ...".
  std::string expected() const;
  // A value checked against the range or the choices; throws std::invalid_argument
  // "expected <expected()>, got <value>".
  double check(double value) const;
  // Text as typed (numbers, fractions such as 1/120, on/off, a choice's name), checked.
  double parse(const std::string& text) const;
  // A value as text that parse() reads back exactly: "0.85", "on", "stable".
  std::string text(double value) const;
  // The field of resolved settings.
  double get(const SolverSettings& s) const;
  void put(SolverSettings& s, double value) const;
};

const std::vector<SettingSpec>& settingTable();
// By key, alias or command-line flag name; null if none.
const SettingSpec* findSetting(const std::string& name);
const SettingSpec& settingOf(const SettingField& field);  // the row of a SolverSettings field
// "n, m, kappa, ..." for messages.
std::string settingKeys();
// Its defaults for the algorithms that read it: "4", "10 (a3, a4, a5, soft: 1)", "off (soft: on)".
std::string defaultsText(const SettingSpec& s);

// --- given settings --------------------------------------------------------------------------

// Settings as a scene file, a command line or a method spec gives them: any subset of the table,
// each value checked when set.
class SolverOverrides {
 public:
  bool has(const SettingSpec& s) const { return set_[s.index]; }
  std::optional<double> value(const SettingSpec& s) const;
  void set(const SettingSpec& s, double value);  // checked: throws std::invalid_argument
  void setText(const SettingSpec& s, const std::string& text) { set(s, s.parse(text)); }
  void clear(const SettingSpec& s) { set_.reset(s.index); }
  std::string text(const SettingSpec& s) const;  // "" when not set

  // By the field they set: o.set(&SolverSettings::kappa, 0.85), o.get(&SolverSettings::kappa).
  template <class T, class U>
  void set(T SolverSettings::*field, U value) {
    const SettingSpec& s = settingOf(field);
    set(s, encode(static_cast<T>(value)));
  }
  template <class T>
  std::optional<T> get(T SolverSettings::*field) const {
    const SettingSpec& s = settingOf(field);
    if (!has(s)) return std::nullopt;
    return decode<T>(v_[s.index]);
  }
  template <class T>
  void clear(T SolverSettings::*field) {
    clear(settingOf(field));
  }
  std::optional<Algorithm> algorithm() const { return get(&SolverSettings::algorithm); }
  std::optional<std::string> preset() const;  // Havok's preset, e.g. "4-medium"
  void setPreset(const std::string& name);

  // Later values win, setting by setting: commandLine.merged(comparePanel).
  SolverOverrides merged(const SolverOverrides& later) const;
  // A scene file's settings under the command line's: as merged(), except that a preset on the
  // command line also replaces the scene's n, m, κ and τ (what a preset sets), so that
  // `--preset 4-medium` means Havok's medium preset on any scene. Values given on the command line
  // next to the preset still win over it (resolve() applies them after the preset).
  SolverOverrides withCommandLine(const SolverOverrides& commandLine) const;
  bool empty() const { return set_.none(); }
  // As a method spec: "a5:n=8:kappa=0.9" ("scene" for no algorithm).
  std::string specText() const;
  bool operator==(const SolverOverrides& o) const;

  template <class T>
  static double encode(T v) {
    if constexpr (std::is_enum_v<T>) return static_cast<double>(static_cast<int>(v) - (std::is_same_v<T, Algorithm> ? 1 : 0));
    else return static_cast<double>(v);
  }
  template <class T>
  static T decode(double v) {
    if constexpr (std::is_enum_v<T>) return static_cast<T>(static_cast<int>(v) + (std::is_same_v<T, Algorithm> ? 1 : 0));
    else if constexpr (std::is_same_v<T, bool>) return v != 0;
    else return static_cast<T>(v);
  }

 private:
  static constexpr size_t kMaxSettings = 64;
  std::array<double, kMaxSettings> v_{};
  std::bitset<kMaxSettings> set_;
};

// Given settings as command-line options: " --kappa 0.85 --no-warm-start".
std::string flagsText(const SolverOverrides& o);

// Refuses what is given explicitly (a command line, a method spec, the page) for an algorithm that
// does not read it: "kappa: a2 does not use κ; a3, a4, a5 do". Throws std::invalid_argument.
// A scene file's settings are not checked: they describe the scene's own algorithm, and another
// algorithm run on the scene leaves what it does not read.
void checkTaken(const SolverOverrides& given, Algorithm a);
void checkTakes(const SettingSpec& s, Algorithm a);

// --- method specs ----------------------------------------------------------------------------
// An algorithm and settings, as `--compare` and the lab write them:
//     a5:n=4:kappa=0.85          a2:m=10:omega=1.3:warm=on
// Settings after the algorithm are key=value (keys or aliases of the table), separated by ':'
// (or ';'). A value may be a list a|b|c: the spec then names the grid of every combination.
// Real values may be written as fractions: h=1/120.
//
// A spec may also name a peer engine instead of an algorithm: `bullet:it=10:h=1/60` is Bullet 3,
// `ode:it=20:sor=1.3` ODE, `mujoco:solver=newton` MuJoCo, stepping the same scene (the lab's
// peers, lab/peers.h). A peer takes h (the table's dt) and it (the table's iterations: its solver
// iterations), some gyro (the table's gyroscopic), and keys of its own (peerTable()). The peers
// themselves are the lab's business; the spec language is the same for every method.
struct PeerSpec {
  const char* name;                   // "ode": what a spec starts with
  const char* engine;                 // "ODE": the engine's own name, for messages
  const char* title;                  // "ODE 0.16 (QuickStep or dWorldStep)"
  std::vector<std::string> tableKeys;  // keys of the settings table it maps: "dt", "iterations", "gyroscopic"
  int iterations;                     // its `it` when a spec does not give it
  std::vector<SettingSpec> own;       // its own keys: ranges, choices, defaults (same for every
                                      // algorithm column) and help; no SolverSettings field
  const SettingSpec* findOwn(const std::string& key) const;  // null if not its own
  std::string keys(const char* last = ", ") const;  // "h, it, gyro, sor, ...", or with last = " and ": "h, it and gyro"
};
const std::vector<PeerSpec>& peerTable();
const PeerSpec* findPeer(const std::string& name);  // null if none
inline constexpr const char* kBulletPeer = "bullet";
inline constexpr const char* kOdePeer = "ode";
inline constexpr const char* kMujocoPeer = "mujoco";

// A peer's own settings, by key (PeerSpec::own), each held as a table value: a choice its index.
using PeerOptions = std::map<std::string, double>;

struct MethodSpec {
  std::string text;            // as written (one combination: the lists resolved)
  SolverOverrides overrides;   // the algorithm and the settings it names (a peer: no algorithm)
  std::string peer;            // "" for substep's algorithms, else the peer's name ("bullet")
  PeerOptions peerOptions;     // a peer's own keys the spec gives
};
// One spec; with value lists, every combination in order (the last key varies fastest).
// Throws std::invalid_argument naming the spec, the key and what was expected.
std::vector<MethodSpec> expandMethodSpec(const std::string& spec);
// A comma-separated list of specs, each expanded.
std::vector<MethodSpec> parseMethodSpecs(const std::string& list);

// Fills what the overrides leave open with the algorithm's defaults (the schema's), after a
// preset when one is given; a value given for a setting the algorithm does not read is left out.
// Throws std::invalid_argument naming the setting when a value is out of range or a preset is
// given to an algorithm without sub-steps.
SolverSettings resolve(const SolverOverrides& o);
// As `substep run SCENE` resolves: the scene's settings under the command line's (withCommandLine),
// what the command line gives checked against the algorithm (checkTaken), a scene's preset dropped
// when the command line asks for an algorithm without one. Throws std::invalid_argument.
SolverSettings resolveFor(const SolverOverrides& scene, const SolverOverrides& commandLine);

// --- lines -----------------------------------------------------------------------------------
// Complete: "a5 (Havok stepping, actual) h=1/60 n=4 m=1 κ=1 τ=0.6 slop=0.001 blocks ..." (every
// setting the algorithm reads); Brief: "a5 n=4 m=1 κ=0.85 τ=0 warm" (the algorithm's main
// settings, and what differs from its defaults); Hud: the algorithm's title and the brief items.
enum class LineDetail { Complete, Brief, Hud };
std::string settingsLine(const SolverSettings& s, LineDetail detail = LineDetail::Complete);

// "1/60" for 0.016666..., else the number: how time steps are printed.
std::string stepText(double dt);

}  // namespace substep

#include "physics/settings.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

namespace substep {

std::string Range::text() const {
  if (std::isinf(hi) && !std::isinf(lo)) return (loOpen ? "> " : ">= ") + numberText(lo);
  return std::string("in ") + (loOpen ? "(" : "[") + numberText(lo) + ", " + numberText(hi) + (hiOpen ? ")" : "]");
}

std::string Range::expected(bool integer) const { return (integer ? "an integer " : "a number ") + text(); }

std::string numberText(double x) {
  char buf[40];
  if (std::isfinite(x) && x == std::floor(x) && std::abs(x) < 1e7) {
    std::snprintf(buf, sizeof buf, "%.0f", x);
    return buf;
  }
  for (int precision = 1; precision <= 17; ++precision) {  // the shortest text that reads back as x
    std::snprintf(buf, sizeof buf, "%.*g", precision, x);
    if (!std::isfinite(x) || std::strtod(buf, nullptr) == x) break;
  }
  // "1e+04" -> "1e4", "1e-06" -> "1e-6"
  std::string t = buf;
  if (const size_t e = t.find('e'); e != std::string::npos) {
    std::string exp = t.substr(e + 1);
    const bool negative = exp[0] == '-';
    exp = exp.substr(exp[0] == '-' || exp[0] == '+' ? 1 : 0);
    exp.erase(0, std::min(exp.find_first_not_of('0'), exp.size() - 1));
    t = t.substr(0, e + 1) + (negative ? "-" : "") + exp;
  }
  return t;
}

const char* algorithmName(Algorithm a) {
  switch (a) {
    case Algorithm::A1: return "a1";
    case Algorithm::A2: return "a2";
    case Algorithm::A3: return "a3";
    case Algorithm::A4: return "a4";
    case Algorithm::A5: return "a5";
    case Algorithm::Soft: return "soft";
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
    case Algorithm::Soft: return "soft step (Box2D v3), an extension";
  }
  return "?";
}

std::optional<Algorithm> parseAlgorithm(const std::string& s) {
  for (Algorithm a : {Algorithm::A1, Algorithm::A2, Algorithm::A3, Algorithm::A4, Algorithm::A5, Algorithm::Soft})
    if (s == algorithmName(a)) return a;
  return std::nullopt;
}

bool havokScaled(Algorithm a) { return a == Algorithm::A3 || a == Algorithm::A4 || a == Algorithm::A5; }
bool subSteps(Algorithm a) { return havokScaled(a) || a == Algorithm::Soft; }

// --- the table -------------------------------------------------------------------------------

namespace {

using O = SolverOverrides;

const std::vector<std::string> kPresets = {"2-soft", "2-medium", "2-hard", "4-soft", "4-medium",
                                           "4-hard", "8-soft", "8-medium", "8-hard"};

std::string listOf(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

// The table. Ranges are what the algorithms can take, not what is sensible for every scene:
// κ = 5 is a poor choice, not an input error.
std::vector<SettingSpec> makeTable() {
  using K = SettingKind;
  return {
      {"algorithm", "algo", "algo", K::Choice, {0, 0}, {"a1", "a2", "a3", "a4", "a5", "soft"},
       "Algorithm: the report's a1 (direct), a2 (PGS/PSOR), a3, a4, a5 (Havok sub-stepping); soft (Box2D v3's "
       "soft step, an extension)",
       &O::algorithm},
      {"dt", "h", "dt", K::Real, {1e-6, 1}, {}, "Time step h [s] (default 1/60)", &O::dt},
      {"substeps", "n", "substeps", K::Integer, {1, 1000}, {}, "Sub-steps n per step (a3-a5, soft; default 4)",
       &O::substeps},
      {"iterations", "m", "iterations", K::Integer, {1, 100000}, {},
       "a2: iteration cap (default 10); a3-a5: micro-iterations m per sub-step; soft: solve and relax sweeps per "
       "sub-step (default 1)",
       &O::iterations},
      {"omega", "ω", "omega", K::Real, {0, 2, true, true}, {}, "a2: over-relaxation ω of PSOR (default 1)", &O::omega},
      {"tolerance", "tol", "tolerance", K::Real, {0, 1e3}, {},
       "a2: stop iterating when no row's velocity changes more [m/s] (default 1e-6)", &O::tolerance},
      {"kappa", "κ", "kappa", K::Real, {0, 10, true}, {}, "κ of a3-a5 (default 1)", &O::kappa},
      {"tau", "τ", "tau", K::Real, {0, 10}, {}, "τ of a3-a5 (default 0.6)", &O::tau},
      {"slop", "", "slop", K::Real, {0, 1}, {}, "Allowed penetration, the report's hi [m] (default 0.001)", &O::slop},
      {"preset", "", "preset", K::Choice, {0, 0}, kPresets,
       "Havok's preset for a3-a5: 2, 4 or 8 sub-steps, soft, medium or hard (sets n, m, κ, τ)", &O::preset},
      {"warm_start", "warm", "warm-start", K::Flag, {0, 0}, {},
       "Start each (sub-)step from the previous one's impulses (an extension; off in the report)", &O::warmStart},
      {"block_solve", "block", "block-solve", K::Flag, {0, 0}, {},
       "Solve unbounded ('stable') joint rows as blocks, as the report's a3-a5 do (a3-a5: on)", &O::blockSolve},
      {"contact_blocks", "cblock", "contact-blocks", K::Flag, {0, 0}, {},
       "Solve each manifold's normal rows together as a small LCP (an extension; off in the report's presets)",
       &O::contactBlocks},
      {"split_impulse", "split", "split-impulse", K::Flag, {0, 0}, {},
       "Correct contact penetration with pseudo-velocities, apart from the velocity solve (an extension)",
       &O::splitImpulse},
      {"motor_unscaled", "", "motor-unscaled", K::Flag, {0, 0}, {},
       "Solve motors with κ = τ = 1 so they reach their speed (an extension, on; off: the report's κ and τ on "
       "every row)",
       &O::motorUnscaled},
      {"friction_exempt", "", "friction-exempt", K::Flag, {0, 0}, {},
       "Keep friction rows out of a4/a5's bias update rule (an extension, on; off: the report's rule on every row)",
       &O::frictionExempt},
      {"speculative", "spec", "speculative", K::Flag, {0, 0}, {},
       "Contact points within a margin before touching, whose gap closes at full speed, not scaled by τ (an "
       "extension, on; the report has none)",
       &O::speculative},
      {"restitution", "", "restitution", K::Flag, {0, 0}, {},
       "Apply the bodies' restitution after the velocity solve (an extension, on; the report has none)",
       &O::restitution},
      {"islands", "", "islands", K::Flag, {0, 0}, {},
       "a5: solve each island (bodies joined by contacts and joints) through all its sub-steps before the next, "
       "while its rows are in cache; the same numbers as all at once (on)",
       &O::islands},
      {"restitution_threshold", "", "restitution-threshold", K::Real, {0, 100}, {},
       "Approach speed below which contacts do not bounce [m/s] (default 1)", &O::restitutionThreshold},
      {"jacobians", "", "jacobians", K::Choice, {0, 0}, {"joints", "stable"},
       "a5: recompute every joint's Jacobian between sub-steps (joints, an extension, the default) or only the "
       "'stable' rows' while micro-iterating (stable, the report's IV.4.1)",
       &O::jacobians},
      {"gyroscopic", "gyro", "gyroscopic", K::Choice, {0, 0}, {"none", "explicit", "implicit"},
       "The gyroscopic term ω × Iω (beyond the report, which has none): none (the default), explicit, or implicit "
       "(one Newton step on the body-frame Euler equation)",
       &O::gyroscopic},
      {"contact_hertz", "", "contact-hertz", K::Real, {0.01, 1e4}, {},
       "soft: contact stiffness as a frequency [Hz] (default 30, at most a quarter of the sub-step rate)",
       &O::contactHertz},
      {"contact_damping", "", "contact-damping", K::Real, {0, 1e3}, {}, "soft: contact damping ratio ζ (default 10)",
       &O::contactDamping},
      {"joint_hertz", "", "joint-hertz", K::Real, {0.01, 1e4}, {},
       "soft: joint stiffness as a frequency [Hz] (default 60, at most a quarter of the sub-step rate)",
       &O::jointHertz},
      {"joint_damping", "", "joint-damping", K::Real, {0, 1e3}, {}, "soft: joint damping ratio ζ (default 2)",
       &O::jointDamping},
      {"push_out", "", "push-out", K::Real, {0, 1e3}, {},
       "soft: largest speed a contact pushes penetrating bodies apart [m/s] (default 3)", &O::pushOut},
  };
}

template <class... F>
struct Overloaded : F... {
  using F::operator()...;
};
template <class... F>
Overloaded(F...) -> Overloaded<F...>;

bool parseFlag(const std::string& v, bool& out) {
  if (v == "on" || v == "1" || v == "true" || v == "yes") return out = true, true;
  if (v == "off" || v == "0" || v == "false" || v == "no") return out = false, true;
  return false;
}

std::string quoted(const std::string& s) {
  std::string q = s.size() > limits::kMaxMessageValue ? s.substr(0, limits::kMaxMessageValue) + "..." : s;
  return "\"" + q + "\"";
}

}  // namespace

const std::vector<SettingSpec>& settingTable() {
  static const std::vector<SettingSpec> table = makeTable();
  return table;
}

const SettingSpec* findSetting(const std::string& name) {
  for (const SettingSpec& s : settingTable())
    if (name == s.key || (s.alias[0] && name == s.alias) || name == s.flag) return &s;
  return nullptr;
}

std::string settingKeys() {
  // The short ASCII name of each: n, m, kappa, ...
  auto ascii = [](const char* t) {
    for (; *t; ++t)
      if (static_cast<unsigned char>(*t) >= 0x80) return false;
    return true;
  };
  std::string s;
  for (const SettingSpec& spec : settingTable()) {
    if (std::string(spec.key) == "algorithm") continue;
    s += (s.empty() ? "" : ", ") + std::string(spec.alias[0] && ascii(spec.alias) ? spec.alias : spec.key);
  }
  return s;
}

std::string SettingSpec::expected() const {
  switch (kind) {
    case SettingKind::Integer: return range.expected(true);
    case SettingKind::Real: return range.expected(false);
    case SettingKind::Flag: return "on or off";
    case SettingKind::Choice: return "one of " + listOf(choices);
  }
  return "";
}

bool SettingSpec::isSet(const SolverOverrides& o) const {
  return std::visit([&](auto m) { return (o.*m).has_value(); }, field);
}

std::string SettingSpec::valueText(const SolverOverrides& o) const {
  return std::visit(Overloaded{[&](std::optional<Algorithm> O::*m) {
                                 return (o.*m) ? std::string(algorithmName(*(o.*m))) : std::string();
                               },
                               [&](std::optional<int> O::*m) { return (o.*m) ? std::to_string(*(o.*m)) : std::string(); },
                               [&](std::optional<double> O::*m) { return (o.*m) ? numberText(*(o.*m)) : std::string(); },
                               [&](std::optional<bool> O::*m) {
                                 return (o.*m) ? std::string(*(o.*m) ? "on" : "off") : std::string();
                               },
                               [&](std::optional<std::string> O::*m) { return (o.*m).value_or(""); }},
                    field);
}

void SettingSpec::copy(const SolverOverrides& from, SolverOverrides& to) const {
  std::visit([&](auto m) { to.*m = from.*m; }, field);
}

void SettingSpec::clear(SolverOverrides& o) const {
  std::visit([&](auto m) { (o.*m).reset(); }, field);
}

void SettingSpec::setNumber(SolverOverrides& o, double x) const {
  const bool integer = kind == SettingKind::Integer;
  if ((kind != SettingKind::Integer && kind != SettingKind::Real) || !range.contains(x) ||
      (integer && x != std::floor(x)))
    throw std::invalid_argument("expected " + expected() + ", got " + numberText(x));
  std::visit(Overloaded{[&](std::optional<int> O::*m) { o.*m = static_cast<int>(x); },
                        [&](std::optional<double> O::*m) { o.*m = x; }, [](auto) {}},
             field);
}

void SettingSpec::setFlag(SolverOverrides& o, bool b) const {
  if (kind != SettingKind::Flag) throw std::invalid_argument("expected " + expected() + ", got " + (b ? "true" : "false"));
  std::visit(Overloaded{[&](std::optional<bool> O::*m) { o.*m = b; }, [](auto) {}}, field);
}

void SettingSpec::setText(SolverOverrides& o, const std::string& text) const {
  const std::invalid_argument bad("expected " + expected() + ", got " + quoted(text));
  switch (kind) {
    case SettingKind::Integer:
    case SettingKind::Real: {
      // Whole text, decimal, finite: "nan", "inf", "1e999", "4x" and "" are refused. A real may
      // be a fraction of two such numbers, "1/120", as time steps are written.
      auto decimal = [&](const std::string& t) {
        const char* begin = t.c_str();
        char* end = nullptr;
        const double x = t.empty() ? NAN : std::strtod(begin, &end);
        if (t.empty() || end != begin + t.size() || !std::isfinite(x) || t.find_first_of("xXpP \t\n") != std::string::npos)
          throw bad;
        return x;
      };
      const size_t slash = text.find('/');
      double x = 0;
      if (slash != std::string::npos && kind == SettingKind::Real) {
        const double q = decimal(text.substr(slash + 1));
        if (q == 0) throw bad;
        x = decimal(text.substr(0, slash)) / q;
        if (!std::isfinite(x)) throw bad;
      } else {
        x = decimal(text);
      }
      try {
        setNumber(o, x);
      } catch (const std::invalid_argument&) {
        throw bad;  // the value as typed
      }
      return;
    }
    case SettingKind::Flag: {
      bool b = false;
      if (!parseFlag(text, b)) throw bad;
      setFlag(o, b);
      return;
    }
    case SettingKind::Choice: {
      bool known = false;
      for (const std::string& c : choices) known = known || c == text;
      if (!known) throw bad;
      std::visit(Overloaded{[&](std::optional<Algorithm> O::*m) { o.*m = parseAlgorithm(text); },
                            [&](std::optional<std::string> O::*m) { o.*m = text; }, [](auto) {}},
                 field);
      return;
    }
  }
}

SolverOverrides SolverOverrides::merged(const SolverOverrides& later) const {
  SolverOverrides r = *this;
  for (const SettingSpec& s : settingTable())
    if (s.isSet(later)) s.copy(later, r);
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

bool SolverOverrides::empty() const {
  for (const SettingSpec& s : settingTable())
    if (s.isSet(*this)) return false;
  return true;
}

// --- method specs ----------------------------------------------------------------------------

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

std::vector<MethodSpec> expandMethodSpec(const std::string& raw) {
  const std::string spec = trim(raw);
  const std::string usage = " (expected e.g. a5:n=4:kappa=0.85)";
  if (spec.empty()) throw std::invalid_argument("an empty method" + usage);
  const std::vector<std::string> parts = split(spec, ":;");
  const std::string algo = trim(parts[0]);
  const std::optional<Algorithm> a = parseAlgorithm(algo);
  const bool bullet = algo == kBulletPeer;
  if (!a && !bullet)
    throw std::invalid_argument(quoted(spec) + ": unknown algorithm " + quoted(algo) +
                                "; a method starts with one of a1, a2, a3, a4, a5, soft, or the peer bullet" + usage);
  // Each key=value (or key=v1|v2|...), checked, in order.
  struct Axis {
    const SettingSpec* setting;
    std::string key;
    std::vector<std::string> values;
  };
  std::vector<Axis> axes;
  size_t combinations = 1;
  for (size_t i = 1; i < parts.size(); ++i) {
    const std::string kv = trim(parts[i]);
    const size_t eq = kv.find('=');
    if (eq == std::string::npos || eq == 0)
      throw std::invalid_argument(quoted(spec) + ": expected key=value, got " + quoted(kv) + usage);
    const std::string key = trim(kv.substr(0, eq));
    const SettingSpec* s = findSetting(bullet && key == "it" ? "iterations" : key);
    if (!s || std::string(s->key) == "algorithm")
      throw std::invalid_argument(quoted(spec) + ": unknown key " + quoted(key) + " (keys: " +
                                  (bullet ? std::string("h, it, gyro") : settingKeys()) + ")");
    const std::string k = s->key;
    if (bullet && k != "dt" && k != "iterations" && k != "gyroscopic")
      throw std::invalid_argument(quoted(spec) + ": the Bullet peer takes h, it and gyro; " + key +
                                  " is a setting of substep's algorithms");
    for (const Axis& x : axes)
      if (x.setting == s) throw std::invalid_argument(quoted(spec) + ": " + key + " is given twice");
    Axis axis{s, key, {}};
    for (const std::string& v : split(kv.substr(eq + 1), "|")) {
      const std::string value = trim(v);
      SolverOverrides probe;
      try {
        s->setText(probe, value);
      } catch (const std::invalid_argument& e) {
        throw std::invalid_argument(quoted(spec) + ": " + key + ": " + e.what());
      }
      axis.values.push_back(value);
    }
    combinations *= axis.values.size();
    if (combinations > 100000) throw std::invalid_argument(quoted(spec) + ": more than 100000 combinations");
    axes.push_back(axis);
  }
  std::vector<MethodSpec> out;
  std::vector<size_t> at(axes.size(), 0);
  for (size_t c = 0; c < combinations; ++c) {
    MethodSpec m;
    m.text = algo;
    m.overrides.algorithm = a;
    if (bullet) m.peer = kBulletPeer;
    for (size_t k = 0; k < axes.size(); ++k) {
      axes[k].setting->setText(m.overrides, axes[k].values[at[k]]);
      m.text += ":" + axes[k].key + "=" + axes[k].values[at[k]];
    }
    out.push_back(m);
    for (size_t k = axes.size(); k-- > 0;) {  // the last key varies fastest
      if (++at[k] < axes[k].values.size()) break;
      at[k] = 0;
    }
  }
  return out;
}

std::vector<MethodSpec> parseMethodSpecs(const std::string& list) {
  std::vector<MethodSpec> out;
  for (const std::string& one : split(list, ",")) {
    const std::vector<MethodSpec> e = expandMethodSpec(one);
    out.insert(out.end(), e.begin(), e.end());
  }
  return out;
}

// --- resolving -------------------------------------------------------------------------------

namespace {

[[noreturn]] void bad(const std::string& field, const std::string& what) {
  throw std::invalid_argument(field + ": " + what);
}

// Havok's presets (docs/algorithms.md): 2, 4 or 8 sub-steps, soft/medium/hard.
void applyPreset(const std::string& name, SolverSettings& s) {
  const auto dash = name.find('-');
  const std::string count = name.substr(0, dash);
  const std::string kind = dash == std::string::npos ? "" : name.substr(dash + 1);
  if ((count != "2" && count != "4" && count != "8") || (kind != "soft" && kind != "medium" && kind != "hard"))
    bad("preset", "expected one of " + listOf(kPresets) + "; got " + quoted(name));
  s.substeps = std::stoi(count);
  if (kind == "soft") { s.tau = 0.3; s.kappa = 0.9; }
  if (kind == "medium") { s.tau = 0.6; s.kappa = 1.0; }
  if (kind == "hard") { s.tau = 0.9; s.kappa = 1.1; }
  s.iterations = 1;
}

}  // namespace

SolverSettings resolve(const SolverOverrides& o) {
  // Every value given is checked against the table, whoever built the overrides.
  for (const SettingSpec& spec : settingTable()) {
    if (!spec.isSet(o) || spec.kind == SettingKind::Flag) continue;
    SolverOverrides probe;
    try {
      spec.setText(probe, spec.valueText(o));
    } catch (const std::invalid_argument& e) {
      bad(spec.key, e.what());
    }
  }
  SolverSettings s;
  s.algorithm = o.algorithm.value_or(Algorithm::A2);
  const bool sub = havokScaled(s.algorithm);
  if (s.algorithm == Algorithm::Soft) {
    // Box2D v3's defaults: 4 sub-steps of one solve and one relax sweep, warm started.
    s.substeps = 4;
    s.iterations = 1;
    s.tau = 1.0;
    s.kappa = 1.0;
    s.warmStart = true;
  } else if (sub) {
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
  if (o.substeps && subSteps(s.algorithm)) s.substeps = *o.substeps;
  if (o.iterations) s.iterations = *o.iterations;
  if (o.omega) s.omega = *o.omega;
  if (o.tolerance) s.tolerance = *o.tolerance;
  if (o.kappa && sub) s.kappa = *o.kappa;
  if (o.tau && sub) s.tau = *o.tau;
  if (o.slop) s.slop = *o.slop;
  if (o.warmStart) s.warmStart = *o.warmStart;
  if (o.blockSolve) s.blockSolve = *o.blockSolve;
  if (o.splitImpulse) s.splitImpulse = *o.splitImpulse;
  if (o.contactBlocks) s.contactBlocks = *o.contactBlocks;
  if (o.motorUnscaled) s.motorUnscaled = *o.motorUnscaled;
  if (o.frictionExempt) s.frictionExempt = *o.frictionExempt;
  if (o.speculative) s.speculative = *o.speculative;
  if (o.restitution) s.restitution = *o.restitution;
  if (o.islands) s.islands = *o.islands;
  if (o.restitutionThreshold) s.restitutionThreshold = *o.restitutionThreshold;
  if (o.jacobians) s.jacobians = *o.jacobians == "stable" ? JacobianRefresh::Stable : JacobianRefresh::Joints;
  if (o.gyroscopic)
    s.gyroscopic = *o.gyroscopic == "implicit" ? Gyroscopic::Implicit
                   : *o.gyroscopic == "explicit" ? Gyroscopic::Explicit
                                                 : Gyroscopic::None;
  if (o.contactHertz) s.contactHertz = *o.contactHertz;
  if (o.contactDamping) s.contactDamping = *o.contactDamping;
  if (o.jointHertz) s.jointHertz = *o.jointHertz;
  if (o.jointDamping) s.jointDamping = *o.jointDamping;
  if (o.pushOut) s.pushOut = *o.pushOut;
  return s;
}

}  // namespace substep

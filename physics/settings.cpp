#include "physics/settings.h"

#include "physics/utf8.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
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

std::string stepText(double dt) {
  // A fraction only when it reads back as the same double, so that a line can be typed again.
  const double n = std::round(1.0 / dt);
  if (n >= 1 && n < 1e9 && 1.0 / n == dt) return "1/" + std::to_string(std::llround(n));
  return numberText(dt);
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
  for (Algorithm a : kAlgorithms)
    if (s == algorithmName(a)) return a;
  return std::nullopt;
}

bool havokScaled(Algorithm a) { return a == Algorithm::A3 || a == Algorithm::A4 || a == Algorithm::A5; }
bool subSteps(Algorithm a) { return havokScaled(a) || a == Algorithm::Soft; }

std::string AlgorithmSet::text() const {
  std::string s;
  for (Algorithm a : kAlgorithms)
    if (has(a)) s += (s.empty() ? "" : ", ") + std::string(algorithmName(a));
  return s;
}

const char* originName(SettingOrigin o) {
  switch (o) {
    case SettingOrigin::Report: return "report";
    case SettingOrigin::Extension: return "extension";
    case SettingOrigin::Limit: return "limit";
  }
  return "?";
}

// --- the table -------------------------------------------------------------------------------

namespace {

using S = SolverSettings;
using A = Algorithm;

const std::vector<std::string> kPresets = {"2-soft", "2-medium", "2-hard", "4-soft", "4-medium",
                                           "4-hard", "8-soft", "8-medium", "8-hard"};

std::string listOf(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

constexpr AlgorithmSet kEvery{A::A1, A::A2, A::A3, A::A4, A::A5, A::Soft};
constexpr AlgorithmSet kIterative{A::A2, A::A3, A::A4, A::A5, A::Soft};
constexpr AlgorithmSet kHavok{A::A3, A::A4, A::A5};
constexpr AlgorithmSet kSubStepping{A::A3, A::A4, A::A5, A::Soft};
constexpr AlgorithmSet kSolved{A::A2, A::A3, A::A4, A::A5};  // rows and blocks by Gauss-Seidel
constexpr AlgorithmSet kNone{};

using Defaults = std::array<double, kAlgorithmCount>;
constexpr Defaults same(double x) { return {x, x, x, x, x, x}; }

// The table. Ranges are what the algorithms can take, not what is sensible for every scene:
// κ = 5 is a poor choice, not an input error. Defaults are given for a1, a2, a3, a4, a5, soft:
// A1/A2 as the report has them (ω 1, 10 iterations, rows one by one), A3-A5 Havok's (n 4, m 1,
// τ 0.6, κ 1, stable joints as blocks), the soft step Box2D v3's (4 sub-steps of one solve and one
// relax sweep, warm started). An algorithm that does not read a setting keeps a neutral value.
std::vector<SettingSpec> makeTable() {
  using K = SettingKind;
  using O = SettingOrigin;
  std::vector<SettingSpec> t = {
      //  key, alias, flag, kind, range, choices, takes, origin, line, brief, help, field, defaults, control
      {"algorithm", "algo", "algo", K::Choice, {0, 0}, {"a1", "a2", "a3", "a4", "a5", "soft"}, kEvery, O::Report, "",
       kNone,
       "Algorithm: the report's a1 (direct), a2 (PGS/PSOR), a3, a4, a5 (Havok sub-stepping); soft (Box2D v3's "
       "soft step, an extension)",
       &S::algorithm, same(1), {}},
      {"dt", "h", "dt", K::Real, {1e-6, 1}, {}, kEvery, O::Report, "h=%s", kNone, "Time step h [s]", &S::dt,
       same(1.0 / 60), {true, "h [s]", 1.0 / 480, 1.0 / 15, 0.0001}},
      {"substeps", "n", "substeps", K::Integer, {1, 1000}, {}, kSubStepping, O::Report, "n=%s", kSubStepping,
       "Sub-steps n per step", &S::substeps, {1, 1, 4, 4, 4, 4}, {true, "n (sub-steps)", 1, 32, 1}},
      {"iterations", "m", "iterations", K::Integer, {1, 100000}, {}, kIterative, O::Report, "m=%s", kSolved,
       "a2: iteration cap; a3-a5: micro-iterations m per sub-step; soft: solve and relax sweeps per sub-step",
       &S::iterations, {10, 10, 1, 1, 1, 1}, {true, "m (iterations)", 1, 100, 1}},
      {"omega", "ω", "omega", K::Real, {0, 2, true, true}, {}, {A::A2}, O::Report, "ω=%s", kNone,
       "a2: over-relaxation ω of PSOR", &S::omega, same(1), {true, "ω", 0.05, 1.95, 0.05}},
      {"tolerance", "tol", "tolerance", K::Real, {0, 1e3}, {}, {A::A2}, O::Report, "tol=%s", kNone,
       "a2: stop iterating when no row's velocity changes more [m/s] (the report's σw)", &S::tolerance, same(1e-6),
       {}},
      {"kappa", "κ", "kappa", K::Real, {0, 10, true}, {}, kHavok, O::Report, "κ=%s", kHavok, "κ of a3-a5", &S::kappa,
       same(1), {true, "κ", 0.05, 2, 0.05}},
      {"tau", "τ", "tau", K::Real, {0, 10}, {}, kHavok, O::Report, "τ=%s", kHavok,
       "τ of a3-a5: the share of the position error corrected per sub-step", &S::tau, {1, 1, 0.6, 0.6, 0.6, 1},
       {true, "τ", 0, 1.5, 0.05}},
      {"slop", "", "slop", K::Real, {0, 1}, {}, kEvery, O::Report, "slop=%s", kNone,
       "Allowed penetration, the report's hi [m]", &S::slop, same(0.001), {}},
      {"preset", "", "preset", K::Choice, {0, 0}, kPresets, kHavok, O::Report, "", kNone,
       "Havok's preset for a3-a5: 2, 4 or 8 sub-steps, soft, medium or hard (sets n, m, κ, τ)", {}, same(0), {}},
      {"warm_start", "warm", "warm-start", K::Flag, {0, 0}, {}, kIterative, O::Extension, "warm", kNone,
       "Start each (sub-)step from the previous one's impulses (an extension; off in the report)", &S::warmStart,
       {0, 0, 0, 0, 0, 1}, {true, "warm start", 0, 0, 0}},
      {"block_solve", "block", "block-solve", K::Flag, {0, 0}, {}, kSolved, O::Report, "blocks", kNone,
       "Solve unbounded ('stable') joint rows as blocks, as the report's a3-a5 do", &S::blockSolve,
       {0, 0, 1, 1, 1, 0}, {}},
      {"contact_blocks", "cblock", "contact-blocks", K::Flag, {0, 0}, {}, kSolved, O::Extension, "cblock", kNone,
       "Solve each manifold's normal rows together as a small LCP (an extension; off in the report's presets)",
       &S::contactBlocks, same(0), {}},
      {"split_impulse", "split", "split-impulse", K::Flag, {0, 0}, {}, kSolved, O::Extension, "split", kNone,
       "Correct contact penetration with pseudo-velocities, apart from the velocity solve (an extension)",
       &S::splitImpulse, same(0), {}},
      {"motor_unscaled", "", "motor-unscaled", K::Flag, {0, 0}, {}, kHavok, O::Extension, "motor-unscaled", kNone,
       "Solve motors with κ = τ = 1 so they reach their speed (an extension; off: the report's κ and τ on every "
       "row)",
       &S::motorUnscaled, same(1), {}},
      {"friction_exempt", "", "friction-exempt", K::Flag, {0, 0}, {}, {A::A4, A::A5, A::Soft}, O::Extension,
       "friction-exempt", kNone,
       "Keep friction rows out of the bias update rule of a4, a5 and the soft step (an extension; off: the "
       "report's rule on every row)",
       &S::frictionExempt, same(1), {}},
      {"speculative", "spec", "speculative", K::Flag, {0, 0}, {}, kEvery, O::Extension, "speculative", kNone,
       "Contact points within a margin before touching, whose gap closes at full speed, not scaled by τ (an "
       "extension; the report has none)",
       &S::speculative, same(1), {}},
      {"restitution", "", "restitution", K::Flag, {0, 0}, {}, kEvery, O::Extension, "restitution", kNone,
       "Apply the bodies' restitution after the velocity solve (an extension; the report has none)",
       &S::restitution, same(1), {}},
      {"islands", "", "islands", K::Flag, {0, 0}, {}, {A::A5}, O::Extension, "islands", kNone,
       "a5: solve each island (bodies joined by contacts and joints) through all its sub-steps before the next, "
       "while its rows are in cache; the same numbers as all at once",
       &S::islands, same(1), {}},
      {"restitution_threshold", "", "restitution-threshold", K::Real, {0, 100}, {}, kEvery, O::Extension,
       "bounce>=%s m/s", kNone, "Approach speed below which contacts do not bounce [m/s]",
       &S::restitutionThreshold, same(1), {}},
      {"jacobians", "", "jacobians", K::Choice, {0, 0}, {"joints", "stable"}, {A::A5}, O::Report, "jacobians=%s",
       kNone,
       "a5: recompute every joint's Jacobian between sub-steps (joints, an extension) or only the 'stable' rows' "
       "while micro-iterating (stable, the report's IV.4.1)",
       &S::jacobians, same(0), {}},
      {"gyroscopic", "gyro", "gyroscopic", K::Choice, {0, 0}, {"none", "explicit", "implicit"}, kEvery,
       O::Extension, "gyro=%s", kNone,
       "The gyroscopic term ω × Iω (beyond the report, which has none): none, explicit, or implicit (one Newton "
       "step on the body-frame Euler equation)",
       &S::gyroscopic, same(0), {}},
      {"contact_order", "", "contact-order", K::Choice, {0, 0}, {"split", "manifold"}, kIterative, O::Extension,
       "order=%s", kNone,
       "The order of contact rows in a sweep: split (every manifold's friction, then every normal row; normals "
       "first when cold) or manifold (each manifold's normal rows, then its friction, as Box2D and Box3D)",
       &S::contactOrder, {0, 0, 0, 0, 0, 1}, {}},
      {"contact_frame", "", "contact-frame", K::Choice, {0, 0}, {"bodies", "world"}, kEvery, O::Extension,
       "frame=%s", kNone,
       "What a contact's normal and arms follow: bodies (formulated from each step's coordinates, as the report's "
       "s2) or world (kept where the narrowphase found them until it runs again for the pair, the separation "
       "following the bodies: Box3D's contact recycling)",
       &S::contactFrame, {0, 0, 0, 0, 0, 1}, {}},
      {"contact_hertz", "", "contact-hertz", K::Real, {0.01, 1e4}, {}, {A::Soft}, O::Extension, "contact %s Hz",
       {A::Soft}, "soft: contact stiffness as a frequency [Hz] (at most a quarter of the sub-step rate)",
       &S::contactHertz, same(30), {}},
      {"contact_damping", "", "contact-damping", K::Real, {0, 1e3}, {}, {A::Soft}, O::Extension, "ζ=%s", kNone,
       "soft: contact damping ratio ζ", &S::contactDamping, same(10), {}},
      {"joint_hertz", "", "joint-hertz", K::Real, {0.01, 1e4}, {}, {A::Soft}, O::Extension, "joint %s Hz", kNone,
       "soft: joint stiffness as a frequency [Hz] (at most a quarter of the sub-step rate)", &S::jointHertz,
       same(60), {}},
      {"joint_damping", "", "joint-damping", K::Real, {0, 1e3}, {}, {A::Soft}, O::Extension, "ζ=%s", kNone,
       "soft: joint damping ratio ζ", &S::jointDamping, same(2), {}},
      {"push_out", "", "push-out", K::Real, {0, 1e3}, {}, {A::Soft}, O::Extension, "push-out %s m/s", kNone,
       "soft: largest speed a contact pushes penetrating bodies apart [m/s]", &S::pushOut, same(3), {}},
      {"sleep", "", "sleep", K::Flag, {0, 0}, {}, kEvery, O::Extension, "sleep", kNone,
       "Islands (bodies joined by contacts) whose bodies all stay below 5 cm/s and 2 deg/s for half a second stop "
       "stepping until a contact with a moving body or a push wakes them; islands with joints stay awake (an "
       "extension; off in the report, the bench and the lab)",
       &S::sleep, same(0), {}},
      {"colours", "", "colours", K::Flag, {0, 0}, {}, {A::Soft}, O::Extension, "colours", kNone,
       "soft: solve the contacts colour by colour (Box2D v3's graph colouring: no two manifolds of a colour share a "
       "moving body), each colour's spread over the threads; off: in the step's order (its levels, or with lanes off "
       "its islands, spread over the threads). A different "
       "order: on the 100-level pyramid a box slides 65 cm in 10 s with it, 22 cm without (docs/algorithms.md)",
       &S::colours, same(0), {}},
      {"lanes", "", "lanes", K::Flag, {0, 0}, {}, {A::A5, A::Soft}, O::Limit, "", kNone,
       "soft, a5: solve the contacts eight manifolds at a time in SIMD lanes (AVX-512, or four an instruction with AVX2 "
       "or without), in runs "
       "that share no moving body: the colours, or without them the step's order cut where it can be (its levels); "
       "the trajectory is the same to the last bit either way (off: one manifold at a time, to compare the speed; "
       "soft: split contact orders are solved so; a5: on one thread, warm, with contact blocks, no joints and "
       "up to about 1000 manifolds, whose lanes fit in the L2 cache)",
       &S::lanes, same(1), {}},
      {"threads", "", "threads", K::Integer, {1, limits::kMaxThreads}, {}, kEvery, O::Limit, "", kNone,
       "Threads a step runs on: the broadphase's queries, the narrowphase, the formulation, the soft step's "
       "contact colours, levels or islands and A5's islands (a large one unit by unit) are shared out; the "
       "trajectory is the same to the last bit for any number (1 in the bench and the lab; serve and render: the "
       "machine's cores for scenes of 3000 moving bodies or more)",
       &S::threads, same(1), {}},
      {"direct_max_rows", "", "direct-max-rows", K::Integer, {1, 20000}, {}, {A::A1}, O::Limit, "rows<=%s", kNone,
       "a1: the largest MLCP it forms as a dense matrix [rows]; larger scenes are refused", &S::directMaxRows,
       same(1500), {}},
      {"direct_work_budget", "", "direct-work-budget", K::Real, {1e3, 1e14}, {}, {A::A1}, O::Limit, "budget=%s flop",
       kNone, "a1: floating-point operations its direct solvers may spend on one step (about 3 s at 2e10)",
       &S::directWorkBudget, same(2e10), {}},
  };
  for (size_t i = 0; i < t.size(); ++i) t[i].index = i;
  return t;
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
  return "\"" + messageValue(s) + "\"";
}

}  // namespace

const std::vector<SettingSpec>& settingTable() {
  static const std::vector<SettingSpec> table = makeTable();
  return table;
}

namespace {

// The peers' own keys (PeerSpec::own): a row of the table's shape with no field, read by no
// algorithm. The defaults are each engine's own.
SettingSpec ownKey(const char* key, SettingKind kind, Range range, std::vector<std::string> choices, const char* line,
                   const char* help, double value) {
  return SettingSpec{key, "", "", kind, range, std::move(choices), kNone, SettingOrigin::Extension, line, kNone, help,
                     std::monostate{}, same(value), {}};
}

std::vector<PeerSpec> makePeerTable() {
  using K = SettingKind;
  std::vector<PeerSpec> t = {
      {kBulletPeer, "Bullet", "Bullet 3 (btDiscreteDynamicsWorld, sequential impulses)", {"dt", "iterations", "gyroscopic"}, 10, {}},
      {kOdePeer,
       "ODE",
       "ODE 0.16 (QuickStep or dWorldStep)",
       {"dt", "iterations", "gyroscopic"},
       20,
       {ownKey("sor", K::Real, {0, 2, true, false}, {}, "sor=%s", "ode: QuickStep's over-relaxation w (ODE's default 1.3)",
               1.3),
        ownKey("step", K::Choice, {0, 0}, {"quick", "big"}, "step=%s",
               "ode: quick (dWorldQuickStep, iterative) or big (dWorldStep, ODE's direct LCP solve)", 0),
        ownKey("erp", K::Real, {0, 1}, {}, "erp=%s", "ode: error reduction parameter of joints and contacts (ODE's 0.2)",
               0.2),
        ownKey("cfm", K::Real, {0, 1}, {}, "cfm=%s", "ode: constraint force mixing of joints and contacts (ODE's 1e-10)",
               1e-10),
        ownKey("layer", K::Real, {0, 1}, {}, "layer=%s",
               "ode: contact surface layer, the depth contacts are left [m]; substep's slop, 1 mm (ODE's own 0 drops a "
               "resting box's contacts each time they reach depth 0, and it falls again)",
               0.001)}},
      {kMujocoPeer,
       "MuJoCo",
       "MuJoCo 2.2 (soft contacts, generalized coordinates)",
       {"dt", "iterations"},
       100,
       {ownKey("solver", K::Choice, {0, 0}, {"newton", "cg", "pgs"}, "solver=%s", "mujoco: constraint solver (MuJoCo's newton)",
               0),
        ownKey("integrator", K::Choice, {0, 0}, {"euler", "rk4", "implicit"}, "integrator=%s",
               "mujoco: euler (semi-implicit, MuJoCo's default), rk4 or implicit (in velocity)", 0),
        ownKey("cone", K::Choice, {0, 0}, {"pyramidal", "elliptic"}, "cone=%s", "mujoco: friction cone (MuJoCo's pyramidal)",
               0),
        ownKey("margin", K::Real, {0, 0.1}, {}, "margin=%s",
               "mujoco: distance within which contacts are found [m]; they act from touching on (gap = margin), so "
               "that bodies exactly touching at the start hold",
               0.001)}},
  };
  for (PeerSpec& p : t)
    for (size_t i = 0; i < p.own.size(); ++i) p.own[i].index = i;
  return t;
}

}  // namespace

const std::vector<PeerSpec>& peerTable() {
  static const std::vector<PeerSpec> table = makePeerTable();
  return table;
}

const PeerSpec* findPeer(const std::string& name) {
  for (const PeerSpec& p : peerTable())
    if (name == p.name) return &p;
  return nullptr;
}

const SettingSpec* PeerSpec::findOwn(const std::string& key) const {
  for (const SettingSpec& s : own)
    if (key == s.key) return &s;
  return nullptr;
}

std::string PeerSpec::keys(const char* last) const {
  std::vector<std::string> k = {"h", "it"};
  for (const std::string& t : tableKeys)
    if (t == "gyroscopic") k.push_back("gyro");
  for (const SettingSpec& o : own) k.push_back(o.key);
  std::string s;
  for (size_t i = 0; i < k.size(); ++i) s += (i == 0 ? "" : i + 1 == k.size() ? last : ", ") + k[i];
  return s;
}

const SettingSpec* findSetting(const std::string& name) {
  for (const SettingSpec& s : settingTable())
    if (name == s.key || (s.alias[0] && name == s.alias) || name == s.flag) return &s;
  return nullptr;
}

const SettingSpec& settingOf(const SettingField& field) {
  for (const SettingSpec& s : settingTable())
    if (s.field == field) return s;
  throw std::logic_error("a SolverSettings field without a row in the settings table");
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

std::string defaultsText(const SettingSpec& s) {
  if (!s.resolved()) return "none";
  // The most common default among the algorithms that read it, then the others.
  std::map<double, std::vector<std::string>> by;
  for (Algorithm a : kAlgorithms)
    if (s.takes.has(a)) by[s.defaultFor(a)].push_back(algorithmName(a));
  auto common = by.begin();
  for (auto it = by.begin(); it != by.end(); ++it)
    if (it->second.size() > common->second.size()) common = it;
  auto text = [&](double v) { return std::string(s.key) == "dt" ? stepText(v) : s.text(v); };
  std::string t = text(common->first), rest;
  for (const auto& [v, algos] : by)
    if (v != common->first) rest += (rest.empty() ? "" : "; ") + listOf(algos) + ": " + text(v);
  return rest.empty() ? t : t + " (" + rest + ")";
}

std::string flagsText(const SolverOverrides& o) {
  std::string line;
  for (const SettingSpec& spec : settingTable()) {
    if (!o.has(spec)) continue;
    const double v = *o.value(spec);
    if (spec.kind == SettingKind::Flag)
      line += std::string(" --") + (v != 0 ? "" : "no-") + spec.flag;
    else
      line += std::string(" --") + spec.flag + " " + (std::string(spec.key) == "dt" ? stepText(v) : spec.text(v));
  }
  return line;
}

SolverSettings::SolverSettings() {
  for (const SettingSpec& s : settingTable())
    if (s.resolved()) s.put(*this, s.defaultFor(Algorithm::A2));
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

double SettingSpec::check(double x) const {
  const bool ok = kind == SettingKind::Flag     ? (x == 0 || x == 1)
                  : kind == SettingKind::Choice ? (x >= 0 && x < static_cast<double>(choices.size()) && x == std::floor(x))
                                                : range.contains(x) && (kind != SettingKind::Integer || x == std::floor(x));
  if (!ok) throw std::invalid_argument("expected " + expected() + ", got " + numberText(x));
  return x;
}

double SettingSpec::parse(const std::string& text) const {
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
        return check(x);
      } catch (const std::invalid_argument&) {
        throw bad;  // the value as typed
      }
    }
    case SettingKind::Flag: {
      bool b = false;
      if (!parseFlag(text, b)) throw bad;
      return b ? 1 : 0;
    }
    case SettingKind::Choice:
      for (size_t i = 0; i < choices.size(); ++i)
        if (choices[i] == text) return static_cast<double>(i);
      throw bad;
  }
  throw bad;
}

std::string SettingSpec::text(double v) const {
  switch (kind) {
    case SettingKind::Integer: return std::to_string(static_cast<long long>(v));
    case SettingKind::Real: return numberText(v);
    case SettingKind::Flag: return v != 0 ? "on" : "off";
    case SettingKind::Choice: return choices.at(static_cast<size_t>(v));
  }
  return "";
}

double SettingSpec::get(const SolverSettings& s) const {
  return std::visit(Overloaded{[](std::monostate) { return 0.0; },
                               [&](auto m) { return SolverOverrides::encode(s.*m); }},
                    field);
}

void SettingSpec::put(SolverSettings& s, double v) const {
  std::visit(Overloaded{[](std::monostate) {},
                        [&](auto m) {
                          using T = std::remove_reference_t<decltype(s.*m)>;
                          s.*m = SolverOverrides::decode<T>(v);
                        }},
             field);
}

// --- given settings --------------------------------------------------------------------------

std::optional<double> SolverOverrides::value(const SettingSpec& s) const {
  if (!has(s)) return std::nullopt;
  return v_[s.index];
}

void SolverOverrides::set(const SettingSpec& s, double value) {
  v_[s.index] = s.check(value);
  set_.set(s.index);
}

std::string SolverOverrides::text(const SettingSpec& s) const { return has(s) ? s.text(v_[s.index]) : std::string(); }

std::optional<std::string> SolverOverrides::preset() const {
  const SettingSpec& s = *findSetting("preset");
  if (!has(s)) return std::nullopt;
  return s.text(v_[s.index]);
}

void SolverOverrides::setPreset(const std::string& name) { setText(*findSetting("preset"), name); }

SolverOverrides SolverOverrides::merged(const SolverOverrides& later) const {
  SolverOverrides r = *this;
  for (const SettingSpec& s : settingTable())
    if (later.has(s)) r.set(s, later.v_[s.index]);
  return r;
}

SolverOverrides SolverOverrides::withCommandLine(const SolverOverrides& commandLine) const {
  SolverOverrides scene = *this;
  if (commandLine.preset()) {  // the preset replaces what it sets, where the scene set it
    scene.clear(&SolverSettings::substeps);
    scene.clear(&SolverSettings::iterations);
    scene.clear(&SolverSettings::kappa);
    scene.clear(&SolverSettings::tau);
  }
  return scene.merged(commandLine);
}

std::string SolverOverrides::specText() const {
  const std::optional<Algorithm> a = algorithm();
  std::string s = a ? algorithmName(*a) : "scene";
  for (const SettingSpec& spec : settingTable()) {
    if (std::string(spec.key) == "algorithm" || !has(spec)) continue;
    const std::string name = spec.alias[0] && static_cast<unsigned char>(spec.alias[0]) < 0x80 ? spec.alias : spec.key;
    s += ":" + name + "=" + text(spec);
  }
  return s;
}

bool SolverOverrides::operator==(const SolverOverrides& o) const {
  if (set_ != o.set_) return false;
  for (size_t i = 0; i < kMaxSettings; ++i)
    if (set_[i] && v_[i] != o.v_[i]) return false;
  return true;
}

void checkTakes(const SettingSpec& s, Algorithm a) {
  if (s.takes.has(a)) return;
  const std::string name = algorithmName(a);
  if (std::string(s.key) == "preset")
    throw std::invalid_argument("preset: presets set Havok's sub-steps, κ and τ, which " + name +
                                " does not use; choose a3, a4 or a5");
  const std::string others = s.takes.text();
  throw std::invalid_argument(std::string(s.key) + ": " + name + " does not use it (" + others +
                              (others.find(',') == std::string::npos ? " does" : " do") +
                              "); leave it out, or choose that algorithm");
}

void checkTaken(const SolverOverrides& given, Algorithm a) {
  for (const SettingSpec& s : settingTable())
    if (given.has(s)) checkTakes(s, a);
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
  const PeerSpec* peer = a ? nullptr : findPeer(algo);
  if (!a && !peer) {
    std::string peers;
    for (const PeerSpec& p : peerTable()) peers += (peers.empty() ? "" : ", ") + std::string(p.name);
    throw std::invalid_argument(quoted(spec) + ": unknown algorithm " + quoted(algo) +
                                "; a method starts with one of a1, a2, a3, a4, a5, soft, or a peer (" + peers + ")" + usage);
  }
  // Each key=value (or key=v1|v2|...), checked, in order.
  struct Axis {
    const SettingSpec* setting;
    std::string key;
    std::vector<std::string> values;
    bool own = false;  // a peer's own key
  };
  std::vector<Axis> axes;
  size_t combinations = 1;
  for (size_t i = 1; i < parts.size(); ++i) {
    const std::string kv = trim(parts[i]);
    const size_t eq = kv.find('=');
    if (eq == std::string::npos || eq == 0)
      throw std::invalid_argument(quoted(spec) + ": expected key=value, got " + quoted(kv) + usage);
    const std::string key = trim(kv.substr(0, eq));
    const SettingSpec* own = peer ? peer->findOwn(key) : nullptr;
    const SettingSpec* s = own ? own : findSetting(peer && key == "it" ? "iterations" : key);
    if (!s || std::string(s->key) == "algorithm")
      throw std::invalid_argument(quoted(spec) + ": unknown key " + quoted(key) + " (keys: " +
                                  (peer ? peer->keys() : settingKeys()) + ")");
    const std::string k = s->key;
    if (peer && !own && std::find(peer->tableKeys.begin(), peer->tableKeys.end(), k) == peer->tableKeys.end())
      throw std::invalid_argument(quoted(spec) + ": the " + peer->engine + " peer takes " + peer->keys(" and ") + "; " + key +
                                  " is a setting of substep's algorithms");
    if (a && !s->takes.has(*a)) {
      try {
        checkTakes(*s, *a);
      } catch (const std::invalid_argument& e) {
        throw std::invalid_argument(quoted(spec) + ": " + e.what());
      }
    }
    for (const Axis& x : axes)
      if (x.setting == s) throw std::invalid_argument(quoted(spec) + ": " + key + " is given twice");
    Axis axis{s, key, {}, own != nullptr};
    for (const std::string& v : split(kv.substr(eq + 1), "|")) {
      const std::string value = trim(v);
      try {
        s->parse(value);
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
    if (a) m.overrides.set(&SolverSettings::algorithm, *a);
    if (peer) m.peer = peer->name;
    for (size_t k = 0; k < axes.size(); ++k) {
      if (axes[k].own)
        m.peerOptions[axes[k].setting->key] = axes[k].setting->parse(axes[k].values[at[k]]);
      else
        m.overrides.setText(*axes[k].setting, axes[k].values[at[k]]);
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

// Havok's presets (docs/algorithms.md): 2, 4 or 8 sub-steps, soft/medium/hard.
void applyPreset(const std::string& name, SolverSettings& s) {
  const auto dash = name.find('-');
  s.substeps = std::stoi(name.substr(0, dash));
  const std::string kind = name.substr(dash + 1);
  if (kind == "soft") { s.tau = 0.3; s.kappa = 0.9; }
  if (kind == "medium") { s.tau = 0.6; s.kappa = 1.0; }
  if (kind == "hard") { s.tau = 0.9; s.kappa = 1.1; }
  s.iterations = 1;
}

}  // namespace

SolverSettings resolve(const SolverOverrides& o) {
  const Algorithm a = o.algorithm().value_or(Algorithm::A2);
  SolverSettings s;
  for (const SettingSpec& spec : settingTable())
    if (spec.resolved()) spec.put(s, spec.defaultFor(a));
  s.algorithm = a;
  if (const std::optional<std::string> preset = o.preset()) {
    if (!havokScaled(a))
      throw std::invalid_argument(std::string("preset: presets set sub-steps, κ and τ, which ") + algorithmName(a) +
                                  " does not use; choose --algo a3, a4 or a5");
    applyPreset(*preset, s);
  }
  for (const SettingSpec& spec : settingTable())
    if (spec.resolved() && o.has(spec) && spec.takes.has(a)) spec.put(s, *o.value(spec));
  return s;
}

SolverSettings resolveFor(const SolverOverrides& scene, const SolverOverrides& commandLine) {
  SolverOverrides use = scene.withCommandLine(commandLine);
  const Algorithm a = use.algorithm().value_or(Algorithm::A2);
  checkTaken(commandLine, a);
  if (!commandLine.preset() && commandLine.algorithm() && use.preset() && !havokScaled(a))
    use.clear(*findSetting("preset"));  // the scene's preset, an algorithm without one asked for
  return resolve(use);
}

// --- lines -----------------------------------------------------------------------------------

std::string settingsLine(const SolverSettings& s, LineDetail detail) {
  const Algorithm a = s.algorithm;
  std::vector<std::string> items;
  for (const SettingSpec& spec : settingTable()) {
    // A row without a line changes no number of the run (threads): settings lines, the HUD and
    // panel labels stay the same on every machine.
    if (!spec.resolved() || !spec.takes.has(a) || std::string(spec.key) == "algorithm" || spec.line[0] == '\0') continue;
    const double v = spec.get(s);
    const bool dt = std::string(spec.key) == "dt";
    const bool shown = detail == LineDetail::Complete || spec.brief.has(a) || (dt && detail == LineDetail::Hud) ||
                       v != spec.defaultFor(a);
    if (!shown) continue;
    if (spec.kind == SettingKind::Flag) {
      if (v != 0) items.push_back(spec.line);
      else if (detail != LineDetail::Complete) items.push_back(std::string("no-") + spec.line);
      continue;
    }
    const std::string value = dt ? stepText(v) : spec.text(v);
    std::string item = spec.line;
    item.replace(item.find("%s"), 2, value);
    items.push_back(item);
  }
  std::string o = algorithmName(a);
  const char* sep = " ";
  if (detail == LineDetail::Complete) o += std::string(" (") + algorithmTitle(a) + ")";
  if (detail == LineDetail::Hud) {
    // The name, then what it is; a title that starts with the name ("soft step ...") stands for both.
    const std::string title = algorithmTitle(a);
    o = title.rfind(o + " ", 0) == 0 ? title : o + " " + title;
    sep = "  ";
  }
  for (const std::string& i : items) o += sep + i;
  return o;
}

}  // namespace substep

// The settings schema: one row per setting (physics/settings.h) for scene files, the command line,
// method specs and JSON, each value read back as written; which algorithms read a setting; method
// specs with value lists; resolve() and Havok's presets.
#include "physics/settings.h"
#include "physics/settings_json.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

using namespace substep;

namespace {

std::string errorOf(const std::string& spec) {
  try {
    expandMethodSpec(spec);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(SettingTable, EveryFieldOnceWithAFlagAndHelp) {
  std::set<std::string> keys, flags, aliases;
  std::set<size_t> fields;
  for (const SettingSpec& s : settingTable()) {
    EXPECT_TRUE(keys.insert(s.key).second) << s.key;
    EXPECT_TRUE(flags.insert(s.flag).second) << s.flag;
    if (s.alias[0]) {
      EXPECT_TRUE(aliases.insert(s.alias).second) << s.alias;
      EXPECT_EQ(findSetting(s.alias), &s);
    }
    EXPECT_GT(std::string(s.help).size(), 10u) << s.key;
    EXPECT_EQ(findSetting(s.key), &s);
    EXPECT_EQ(findSetting(s.flag), &s);
    EXPECT_EQ(&settingTable()[s.index], &s);
    if (s.resolved()) {
      EXPECT_EQ(&settingOf(s.field), &s) << s.key << ": two rows set one field";
    }
    EXPECT_NE(s.takes.text(), "") << s.key << ": no algorithm reads it";
  }
  // Every field of SolverSettings has its row: the binding below names each field once (a new
  // field breaks its count), and the table holds as many resolved rows.
  SolverSettings st;
  auto& [algorithm, dt, n, m, omega, tol, kappa, tau, slop, warm, block, cblock, split, motor, friction, spec, rest,
         threshold, islands, jacobians, gyro, order, frame, ch, cd, jh, jd, push, sleep, threads, colours, lanes, rows, budget] = st;
  const size_t bound = 34;
  (void)algorithm, (void)dt, (void)n, (void)m, (void)omega, (void)tol, (void)kappa, (void)tau, (void)slop, (void)warm;
  (void)block, (void)cblock, (void)split, (void)motor, (void)friction, (void)spec, (void)rest, (void)threshold;
  (void)islands, (void)jacobians, (void)gyro, (void)order, (void)frame, (void)ch, (void)cd, (void)jh, (void)jd, (void)push, (void)sleep, (void)threads, (void)colours, (void)lanes, (void)rows,
      (void)budget;
  size_t resolvedRows = 0;
  for (const SettingSpec& s : settingTable()) resolvedRows += s.resolved();
  EXPECT_EQ(resolvedRows, bound);
}

// Every value a setting can take, written by each writer of the schema, is read back the same.
TEST(Schema, AValueWrittenIsReadBackTheSame) {
  std::mt19937 rng(7);
  int checked = 0;
  for (const SettingSpec& s : settingTable()) {
    std::vector<double> values;
    switch (s.kind) {
      case SettingKind::Flag: values = {0, 1}; break;
      case SettingKind::Choice:
        for (size_t i = 0; i < s.choices.size(); ++i) values.push_back(static_cast<double>(i));
        break;
      case SettingKind::Integer:
        values = {s.range.lo, std::min(s.range.hi, s.range.lo + 1), s.range.hi};
        break;
      case SettingKind::Real: {
        const double lo = std::max(s.range.lo, -1e6), hi = std::min(s.range.hi, 1e6);
        for (int k = 0; k < 20; ++k) values.push_back(std::uniform_real_distribution<double>(lo, hi)(rng));
        if (!s.range.loOpen) values.push_back(s.range.lo);
        if (!s.range.hiOpen) values.push_back(s.range.hi);
        values.push_back(1.0 / 60);
        values.erase(std::remove_if(values.begin(), values.end(), [&](double v) { return !s.range.contains(v); }),
                     values.end());
        break;
      }
    }
    for (const double v : values) {
      ++checked;
      // As text (method specs, the command line): the shortest text that reads back.
      EXPECT_EQ(s.parse(s.text(v)), v) << s.key << " " << s.text(v);
      // As JSON (records, the server).
      SolverOverrides o;
      o.set(s, v);
      const SolverOverrides back = overridesFromJson(overridesJson(o), "x");
      EXPECT_TRUE(back == o) << s.key << " " << overridesJson(o).dump();
      // As a method spec.
      if (std::string(s.key) != "algorithm" && std::string(s.key) != "preset") {
        SolverOverrides a;
        const Algorithm algo = [&] {
          for (Algorithm x : kAlgorithms)
            if (s.takes.has(x)) return x;
          return Algorithm::A2;
        }();
        a.set(&SolverSettings::algorithm, algo);
        a.set(s, v);
        const std::vector<MethodSpec> spec = expandMethodSpec(a.specText());
        ASSERT_EQ(spec.size(), 1u) << a.specText();
        EXPECT_TRUE(spec[0].overrides == a) << a.specText();
        // Resolved, and out as the JSON of resolved settings.
        if (s.resolved()) {
          const SolverSettings r = resolve(a);
          EXPECT_EQ(s.get(r), v) << s.key;
          const SolverOverrides fromResolved = overridesFromJson(settingsJson(r), "x");
          EXPECT_EQ(s.get(resolve(fromResolved)), v) << s.key;
          EXPECT_EQ(settingsJson(resolve(fromResolved)), settingsJson(r)) << s.key;
        }
      }
    }
  }
  std::printf("%d values of %zu settings written and read back\n", checked, settingTable().size());
}

// Every output of the schema names every key it should.
TEST(Schema, EveryOutputNamesEveryKey) {
  const SolverSettings st;
  const nlohmann::json resolved = settingsJson(st), schema = schemaJson();
  ASSERT_EQ(schema.size(), settingTable().size());
  for (const SettingSpec& s : settingTable()) {
    EXPECT_EQ(resolved.contains(s.key), s.resolved()) << s.key;
    EXPECT_EQ(schema[s.index]["key"], s.key);
    EXPECT_FALSE(schema[s.index]["takes"].empty()) << s.key;
    EXPECT_EQ(schema[s.index]["defaults"].size(), 6u) << s.key;
  }
  // The complete line names every setting the algorithm reads: numbers and choices always, flags when on;
  // but those with no line item, which change no number (threads, lanes: tests/test_threads.cpp and
  // tests/test_lanes.cpp hold their trajectories to the last bit), so that a line or an image is the
  // same on any machine.
  for (Algorithm a : kAlgorithms) {
    SolverOverrides o;
    o.set(&SolverSettings::algorithm, a);
    SolverSettings r = resolve(o);
    for (const SettingSpec& s : settingTable())
      if (s.kind == SettingKind::Flag && s.resolved()) s.put(r, 1);
    const std::string line = settingsLine(r);
    for (const SettingSpec& s : settingTable()) {
      if (!s.resolved() || std::string(s.key) == "algorithm" || std::string(s.line).empty()) continue;
      std::string item = s.line;
      item = item.substr(0, item.find("%s"));
      EXPECT_EQ(line.find(item) != std::string::npos, s.takes.has(a)) << algorithmName(a) << " " << s.key << ": " << line;
    }
  }
}

// The HUD names the algorithm and what it is, once: "a5 Havok stepping, actual", and the soft
// step by its title alone, which starts with its name.
TEST(Schema, TheHudNamesTheAlgorithmOnce) {
  for (Algorithm a : kAlgorithms) {
    SolverOverrides o;
    o.set(&SolverSettings::algorithm, a);
    const std::string hud = settingsLine(resolve(o), LineDetail::Hud), name = algorithmName(a);
    EXPECT_EQ(hud.find(name), 0u) << hud;
    EXPECT_NE(hud.find(algorithmTitle(a)), std::string::npos) << hud;
    EXPECT_EQ(hud.find(name + " " + name), std::string::npos) << hud;
  }
}

// Each algorithm's defaults are the schema's, and a value given for a setting the algorithm
// does not read is refused when given explicitly, left out when a scene gives it.
TEST(Schema, DefaultsAndWhichAlgorithmsReadASetting) {
  for (Algorithm a : kAlgorithms) {
    SolverOverrides o;
    o.set(&SolverSettings::algorithm, a);
    const SolverSettings r = resolve(o);
    for (const SettingSpec& s : settingTable())
      if (s.resolved() && std::string(s.key) != "algorithm") {
        EXPECT_EQ(s.get(r), s.defaultFor(a)) << s.key;
      }
  }
  SolverOverrides scene, cl;
  scene.set(&SolverSettings::kappa, 0.85);  // pyramid.json's, for a5
  cl.set(&SolverSettings::algorithm, Algorithm::A2);
  EXPECT_EQ(resolveFor(scene, cl).kappa, 1.0);  // a2 leaves it
  cl.set(&SolverSettings::kappa, 0.9);
  try {
    resolveFor(scene, cl);
    ADD_FAILURE() << "kappa given to a2";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "kappa: a2 does not use it (a3, a4, a5 do); leave it out, or choose that algorithm");
  }
  EXPECT_NE(errorOf("a5:omega=1.3").find("omega: a5 does not use it (a2 does)"), std::string::npos) << errorOf("a5:omega=1.3");
  EXPECT_NE(errorOf("a1:split=on").find("split_impulse: a1 does not use it"), std::string::npos) << errorOf("a1:split=on");
  EXPECT_EQ(errorOf("a2:split=on"), "");
}

TEST(SettingTable, TextIsParsedWholeAndWithinRange) {
  const SettingSpec& kappa = *findSetting("kappa");
  SolverOverrides o;
  for (const char* bad : {"nan", "inf", "-inf", "1e999", "0", "10.5", "", "1x", "0x1p3", " 1"}) {
    try {
      o.setText(kappa, bad);
      ADD_FAILURE() << "kappa accepted \"" << bad << "\"";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), std::string("expected a number in (0, 10], got \"") + bad + "\"");
    }
  }
  o.setText(kappa, "0.85");
  EXPECT_DOUBLE_EQ(*o.get(&SolverSettings::kappa), 0.85);
  const SettingSpec& n = *findSetting("n");
  EXPECT_THROW(o.setText(n, "2.5"), std::invalid_argument);
  EXPECT_THROW(o.set(n, 1001), std::invalid_argument);
  o.set(n, 8);
  EXPECT_EQ(*o.get(&SolverSettings::substeps), 8);
  EXPECT_THROW(o.setText(*findSetting("warm"), "maybe"), std::invalid_argument);
  EXPECT_THROW(o.setText(*findSetting("algorithm"), "a6"), std::invalid_argument);
}

// Values set in code are checked against the same table when set.
TEST(SettingTable, EveryValueIsCheckedWhenSet) {
  SolverOverrides o;
  try {
    o.set(&SolverSettings::kappa, 850);
    ADD_FAILURE();
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "expected a number in (0, 10], got 850");
  }
  EXPECT_THROW(o.set(&SolverSettings::dt, 1e-300), std::invalid_argument);
  o.set(&SolverSettings::dt, 0.01);
  EXPECT_EQ(resolve(o).dt, 0.01);
}

TEST(MethodSpecs, ValueListsNameAGrid) {
  const auto specs = expandMethodSpec("a5:n=1|2|4|8:m=1");
  ASSERT_EQ(specs.size(), 4u);
  EXPECT_EQ(specs[2].text, "a5:n=4:m=1");
  EXPECT_EQ(*specs[2].overrides.get(&SolverSettings::substeps), 4);
  EXPECT_EQ(*specs[2].overrides.get(&SolverSettings::iterations), 1);
  const auto grid = expandMethodSpec("a3:n=2|4:kappa=0.9|1");  // the last key varies fastest
  ASSERT_EQ(grid.size(), 4u);
  EXPECT_EQ(grid[1].text, "a3:n=2:kappa=1");
  EXPECT_EQ(grid[2].text, "a3:n=4:kappa=0.9");
  const auto list = parseMethodSpecs("a2:m=4, a5:n=4:warm=on");
  ASSERT_EQ(list.size(), 2u);
  EXPECT_TRUE(*list[1].overrides.get(&SolverSettings::warmStart));
  EXPECT_EQ(*list[0].overrides.algorithm(), Algorithm::A2);
}

TEST(MethodSpecs, ErrorsNameTheSpecAndTheKey) {
  EXPECT_NE(errorOf("a9").find("unknown algorithm \"a9\""), std::string::npos) << errorOf("a9");
  EXPECT_NE(errorOf("a5:n=0").find("n: expected an integer in [1, 1000], got \"0\""), std::string::npos);
  EXPECT_NE(errorOf("a5:n=2|x").find("n: expected an integer"), std::string::npos);
  EXPECT_NE(errorOf("a5:frob=1").find("unknown key \"frob\""), std::string::npos);
  EXPECT_NE(errorOf("a5:n").find("expected key=value"), std::string::npos);
  EXPECT_NE(errorOf("a5:n=2:n=4").find("n is given twice"), std::string::npos);
  EXPECT_NE(errorOf("").find("an empty method"), std::string::npos);
  EXPECT_NE(errorOf("a5:n=1|2|3|4|5|6|7|8|9|10:m=1|2|3|4|5|6|7|8|9|10:kappa=1|2|3|4|5|6|7|8|9|10:"
                    "tau=0|1|2|3|4|5|6|7|8|9:dt=0.1|0.2|0.3|0.4|0.5|0.6|0.7|0.8|0.9|1:slop=0|0.1")
                .find("more than 100000 combinations"),
            std::string::npos);
}

// Time steps are written as fractions in specs and on the command line; only reals take them.
TEST(SettingTable, RealsMayBeFractions) {
  SolverOverrides o;
  o.setText(*findSetting("h"), "1/120");
  EXPECT_DOUBLE_EQ(*o.get(&SolverSettings::dt), 1.0 / 120);
  for (const char* bad : {"1/0", "1/", "/60", "1/60/2", "1/x", "1e308/1e-308"})
    EXPECT_THROW(o.setText(*findSetting("h"), bad), std::invalid_argument) << bad;
  EXPECT_THROW(o.setText(*findSetting("h"), "2/1"), std::invalid_argument);  // 2 s: beyond (0, 1]
  EXPECT_THROW(o.setText(*findSetting("n"), "8/2"), std::invalid_argument);  // integers are whole numbers
  const auto grid = expandMethodSpec("a1:h=1/60|1/120");
  ASSERT_EQ(grid.size(), 2u);
  EXPECT_EQ(grid[1].text, "a1:h=1/120");
  EXPECT_DOUBLE_EQ(resolve(grid[1].overrides).dt, 1.0 / 120);
}

// Bullet is a method like the algorithms: the same parser, value lists and errors, with the
// settings the peer maps.
TEST(MethodSpecs, TheBulletPeerTakesItsOwnSettings) {
  const auto specs = parseMethodSpecs("bullet:it=10|20:h=1/120,a2:m=4");
  ASSERT_EQ(specs.size(), 3u);
  EXPECT_EQ(specs[0].peer, "bullet");
  EXPECT_EQ(specs[0].text, "bullet:it=10:h=1/120");
  EXPECT_FALSE(specs[0].overrides.algorithm());
  EXPECT_EQ(*specs[1].overrides.get(&SolverSettings::iterations), 20);
  EXPECT_DOUBLE_EQ(*specs[1].overrides.get(&SolverSettings::dt), 1.0 / 120);
  EXPECT_EQ(specs[2].peer, "");
  EXPECT_EQ(expandMethodSpec("bullet:gyro=none")[0].overrides.get(&SolverSettings::gyroscopic).value(), Gyroscopic::None);
  EXPECT_NE(errorOf("bullet:kappa=0.9").find("the Bullet peer takes h, it and gyro; kappa"), std::string::npos)
      << errorOf("bullet:kappa=0.9");
  EXPECT_NE(errorOf("bullet:frob=1").find("unknown key \"frob\" (keys: h, it, gyro)"), std::string::npos);
  EXPECT_NE(errorOf("a5:it=4").find("unknown key \"it\""), std::string::npos);  // "it" is Bullet's word
  EXPECT_NE(errorOf("havok").find("or a peer (bullet, ode, mujoco)"), std::string::npos) << errorOf("havok");
}

// ODE and MuJoCo take h and it as Bullet does, and keys of their own, checked as the table's.
TEST(MethodSpecs, OdeAndMujocoTakeTheirOwnKeys) {
  const auto ode = parseMethodSpecs("ode:it=20:sor=1|1.3:step=big:erp=0.5:cfm=1e-5");
  ASSERT_EQ(ode.size(), 2u);
  EXPECT_EQ(ode[1].peer, "ode");
  EXPECT_EQ(ode[1].text, "ode:it=20:sor=1.3:step=big:erp=0.5:cfm=1e-5");
  EXPECT_EQ(*ode[1].overrides.get(&SolverSettings::iterations), 20);
  EXPECT_DOUBLE_EQ(ode[0].peerOptions.at("sor"), 1);
  EXPECT_DOUBLE_EQ(ode[1].peerOptions.at("sor"), 1.3);
  EXPECT_DOUBLE_EQ(ode[1].peerOptions.at("step"), 1);  // big: the choice's index
  EXPECT_EQ(ode[1].peerOptions.count("layer"), 0u);    // given keys only; the lab fills the defaults
  const auto mj = expandMethodSpec("mujoco:solver=pgs:integrator=rk4:cone=elliptic:margin=0.002:h=1/240");
  ASSERT_EQ(mj.size(), 1u);
  EXPECT_EQ(mj[0].peer, "mujoco");
  EXPECT_DOUBLE_EQ(mj[0].peerOptions.at("solver"), 2);
  EXPECT_DOUBLE_EQ(mj[0].peerOptions.at("margin"), 0.002);
  EXPECT_DOUBLE_EQ(*mj[0].overrides.get(&SolverSettings::dt), 1.0 / 240);
  EXPECT_NE(errorOf("ode:sor=3").find("sor: expected a number in (0, 2], got \"3\""), std::string::npos) << errorOf("ode:sor=3");
  EXPECT_NE(errorOf("ode:step=slow").find("expected one of quick, big"), std::string::npos);
  EXPECT_NE(errorOf("mujoco:gyro=none").find("the MuJoCo peer takes h, it, solver, integrator, cone and margin; gyro"),
            std::string::npos)
      << errorOf("mujoco:gyro=none");
  EXPECT_NE(errorOf("mujoco:sor=1").find("unknown key \"sor\" (keys: h, it, solver, integrator, cone, margin)"),
            std::string::npos)
      << errorOf("mujoco:sor=1");
  EXPECT_NE(errorOf("ode:kappa=1").find("the ODE peer takes h, it, gyro, sor, step, erp, cfm and layer; kappa"),
            std::string::npos)
      << errorOf("ode:kappa=1");
}

TEST(Presets, HavoksThreeStiffnesses) {
  SolverOverrides o;
  o.set(&SolverSettings::algorithm, Algorithm::A4);
  o.setPreset("8-hard");
  const SolverSettings s = resolve(o);
  EXPECT_EQ(s.substeps, 8);
  EXPECT_EQ(s.iterations, 1);
  EXPECT_DOUBLE_EQ(s.tau, 0.9);
  EXPECT_DOUBLE_EQ(s.kappa, 1.1);
  o.set(&SolverSettings::algorithm, Algorithm::A2);  // presets are sub-stepping settings
  EXPECT_THROW(resolve(o), std::invalid_argument);
}

TEST(NumberText, ShortestRoundTrip) {
  EXPECT_EQ(numberText(10000), "10000");
  EXPECT_EQ(numberText(1e-6), "1e-6");
  EXPECT_EQ(numberText(1e9), "1e9");
  EXPECT_EQ(numberText(0.85), "0.85");
  EXPECT_EQ(numberText(1.0 / 3), "0.3333333333333333");
  EXPECT_EQ(numberText(-1e155), "-1e155");
}

// Records and recordings written before `threads` and `colours` existed still open: they ran on
// one thread, uncoloured. And no settings line (the HUD, panel labels, record lines) names the
// threads, which change no number of the run: a snapshot drawn on 2 cores and on 64 is the same.
TEST(Schema, ThreadsAndColoursAreOptionalInOldRecordsAndThreadsInNoLine) {
  SolverOverrides o;
  o.set(&SolverSettings::algorithm, Algorithm::Soft);
  SolverSettings st = resolve(o);
  st.threads = 8;
  st.colours = true;
  nlohmann::json j = settingsJson(st);
  j.erase("threads");
  j.erase("colours");
  const SolverSettings back = resolvedFromJson(j, "old.rec");
  EXPECT_EQ(back.threads, 1);
  EXPECT_FALSE(back.colours);
  j.erase("dt");
  EXPECT_THROW(resolvedFromJson(j, "old.rec"), std::invalid_argument);  // any other missing key is refused
  for (LineDetail d : {LineDetail::Brief, LineDetail::Hud, LineDetail::Complete}) {
    const std::string line = settingsLine(st, d);
    EXPECT_EQ(line.find("threads"), std::string::npos) << line;
  }
}

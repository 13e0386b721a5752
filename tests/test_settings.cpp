// The solver settings' table: one range per setting for scene files, the command line and
// method specs; method specs with value lists; resolve() and Havok's presets.
#include "physics/settings.h"

#include <gtest/gtest.h>

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
  }
  // Setting each from text and reading it back covers every field of SolverOverrides.
  SolverOverrides o;
  for (const SettingSpec& s : settingTable()) {
    const std::string v = s.kind == SettingKind::Flag     ? "on"
                          : s.kind == SettingKind::Choice ? s.choices.front()
                                                          : numberText(s.range.hi);
    if (s.kind == SettingKind::Real && s.range.hiOpen) continue;
    s.setText(o, v);
    EXPECT_EQ(s.valueText(o), v) << s.key;
  }
  EXPECT_FALSE(o.empty());
  EXPECT_TRUE(SolverOverrides{}.empty());
}

TEST(SettingTable, TextIsParsedWholeAndWithinRange) {
  const SettingSpec& kappa = *findSetting("kappa");
  SolverOverrides o;
  for (const char* bad : {"nan", "inf", "-inf", "1e999", "0", "10.5", "", "1x", "0x1p3", " 1"}) {
    try {
      kappa.setText(o, bad);
      ADD_FAILURE() << "kappa accepted \"" << bad << "\"";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), std::string("expected a number in (0, 10], got \"") + bad + "\"");
    }
  }
  kappa.setText(o, "0.85");
  EXPECT_DOUBLE_EQ(*o.kappa, 0.85);
  const SettingSpec& n = *findSetting("n");
  EXPECT_THROW(n.setText(o, "2.5"), std::invalid_argument);
  EXPECT_THROW(n.setNumber(o, 1001), std::invalid_argument);
  n.setNumber(o, 8);
  EXPECT_EQ(*o.substeps, 8);
  EXPECT_THROW(findSetting("warm")->setText(o, "maybe"), std::invalid_argument);
  EXPECT_THROW(findSetting("algorithm")->setText(o, "a6"), std::invalid_argument);
}

// Overrides built in code are checked by resolve() against the same table.
TEST(SettingTable, ResolveChecksEveryValue) {
  SolverOverrides o;
  o.algorithm = Algorithm::A5;
  o.kappa = 850;
  try {
    resolve(o);
    ADD_FAILURE();
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "kappa: expected a number in (0, 10], got \"850\"");  // as valueText gives it
  }
  o.kappa.reset();
  o.dt = 1e-300;
  EXPECT_THROW(resolve(o), std::invalid_argument);
  o.dt = 0.01;
  EXPECT_EQ(resolve(o).dt, 0.01);
}

TEST(MethodSpecs, ValueListsNameAGrid) {
  const auto specs = expandMethodSpec("a5:n=1|2|4|8:m=1");
  ASSERT_EQ(specs.size(), 4u);
  EXPECT_EQ(specs[2].text, "a5:n=4:m=1");
  EXPECT_EQ(*specs[2].overrides.substeps, 4);
  EXPECT_EQ(*specs[2].overrides.iterations, 1);
  const auto grid = expandMethodSpec("a3:n=2|4:kappa=0.9|1");  // the last key varies fastest
  ASSERT_EQ(grid.size(), 4u);
  EXPECT_EQ(grid[1].text, "a3:n=2:kappa=1");
  EXPECT_EQ(grid[2].text, "a3:n=4:kappa=0.9");
  const auto list = parseMethodSpecs("a2:m=4, a5:n=4:warm=on");
  ASSERT_EQ(list.size(), 2u);
  EXPECT_TRUE(*list[1].overrides.warmStart);
  EXPECT_EQ(*list[0].overrides.algorithm, Algorithm::A2);
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
  findSetting("h")->setText(o, "1/120");
  EXPECT_DOUBLE_EQ(*o.dt, 1.0 / 120);
  for (const char* bad : {"1/0", "1/", "/60", "1/60/2", "1/x", "1e308/1e-308"})
    EXPECT_THROW(findSetting("h")->setText(o, bad), std::invalid_argument) << bad;
  EXPECT_THROW(findSetting("h")->setText(o, "2/1"), std::invalid_argument);  // 2 s: beyond (0, 1]
  EXPECT_THROW(findSetting("n")->setText(o, "8/2"), std::invalid_argument);  // integers are whole numbers
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
  EXPECT_FALSE(specs[0].overrides.algorithm);
  EXPECT_EQ(*specs[1].overrides.iterations, 20);
  EXPECT_DOUBLE_EQ(*specs[1].overrides.dt, 1.0 / 120);
  EXPECT_EQ(specs[2].peer, "");
  EXPECT_EQ(expandMethodSpec("bullet:gyro=none")[0].overrides.gyroscopic.value(), "none");
  EXPECT_NE(errorOf("bullet:kappa=0.9").find("the Bullet peer takes h, it and gyro; kappa"), std::string::npos)
      << errorOf("bullet:kappa=0.9");
  EXPECT_NE(errorOf("bullet:frob=1").find("unknown key \"frob\" (keys: h, it, gyro)"), std::string::npos);
  EXPECT_NE(errorOf("a5:it=4").find("unknown key \"it\""), std::string::npos);  // "it" is Bullet's word
  EXPECT_NE(errorOf("ode").find("or the peer bullet"), std::string::npos);
}

TEST(Presets, HavoksThreeStiffnesses) {
  SolverOverrides o;
  o.algorithm = Algorithm::A4;
  o.preset = "8-hard";
  const SolverSettings s = resolve(o);
  EXPECT_EQ(s.substeps, 8);
  EXPECT_EQ(s.iterations, 1);
  EXPECT_DOUBLE_EQ(s.tau, 0.9);
  EXPECT_DOUBLE_EQ(s.kappa, 1.1);
  o.algorithm = Algorithm::A2;  // presets are sub-stepping settings
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

// The substep executable: exit statuses, messages, outputs. Runs the built binary.
#include "run_substep.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <sstream>
#include <string>

namespace fs = std::filesystem;

namespace {

using substep_test::Outcome;

Outcome run(const std::string& args) { return substep_test::runSubstep(args); }

// A folder per test: CTest runs the tests in parallel, and some look at what is in theirs.
fs::path scratch(const std::string& name) {
  const fs::path d = substep_test::scratchFolder("test_cli_out");
  fs::create_directories(d);
  return d / name;
}

std::vector<std::vector<std::string>> readCsv(const fs::path& f) {
  std::ifstream in(f);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) cells.push_back(c);
    rows.push_back(cells);
  }
  return rows;
}

}  // namespace

// Every kind of bad scene file: exit status 2 and a message naming the file, the JSON path and
// what was expected.
TEST(Cli, BadSceneFilesExitWithStatus2AndSayWhy) {
  const std::map<std::string, std::vector<std::string>> cases = {
      {"syntax.json", {"syntax.json:4:5", "JSON syntax error"}},
      {"wrong_type.json", {"bodies[0].shape.radius", "expected a number > 0, got string"}},
      {"missing_field.json", {"bodies[0].shape", "missing required field \"half_extents\""}},
      {"misspelt_key.json", {"bodies[0].shape", "unknown key \"radus\""}},
      {"negative_mass.json", {"bodies[0].mass", "expected a number > 0, got -2"}},
      {"zero_size.json", {"bodies[0].shape.half_height", "expected a number > 0, got 0"}},
      {"unknown_joint_type.json", {"joints[0].type", "unknown joint type \"slider\"", "ball, hinge"}},
      {"joint_unknown_body.json", {"joints[0].bodies[1]", "unknown body"}},
      {"static_with_mass.json", {"bodies[0].mass", "static bodies take no mass"}},
      {"only_static.json", {"at least one dynamic body"}},
  };
  for (const auto& [file, fragments] : cases) {
    const Outcome r = run("run tests/data/bad/" + file + " --steps 1");
    EXPECT_EQ(r.status, 2) << file << ": " << r.output;
    EXPECT_NE(r.output.find("tests/data/bad/" + file), std::string::npos) << r.output;
    for (const std::string& f : fragments) EXPECT_NE(r.output.find(f), std::string::npos) << file << ": " << r.output;
  }
  // Every fixture is covered.
  int files = 0;
  for (const auto& e : fs::directory_iterator(SUBSTEP_SOURCE_DIR "/tests/data/bad")) files += e.path().extension() == ".json";
  EXPECT_EQ(files, static_cast<int>(cases.size()));
}

TEST(Cli, BadArgumentsExitWithStatus2) {
  Outcome r = run("run assets/scenes/no_such_scene.json");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("cannot open"), std::string::npos) << r.output;
  r = run("run assets/scenes/stack.json --algo a9");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("--algo"), std::string::npos) << r.output;
  r = run("run assets/scenes/stack.json --algo a2 --substeps 4");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("does not sub-step"), std::string::npos) << r.output;
  r = run("run assets/scenes/stack.json --steps 10 --seconds 1");
  EXPECT_EQ(r.status, 2);
  r = run("run assets/scenes/stack.json --steps 1 --trajectory /proc/forbidden/t.csv");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("/proc/forbidden"), std::string::npos) << r.output;
  r = run("frobnicate");
  EXPECT_EQ(r.status, 2);
}

TEST(Cli, EveryCommandHasHelp) {
  for (const std::string c : {"", "run ", "scenes "}) {
    const Outcome r = run(c + "--help");
    EXPECT_EQ(r.status, 0) << c;
    EXPECT_NE(r.output.find("Usage"), std::string::npos) << r.output;
  }
  EXPECT_NE(run("run --help").output.find("--trajectory"), std::string::npos);
}

TEST(Cli, ScenesListsFilesAndGenerators) {
  const Outcome r = run("scenes");
  EXPECT_EQ(r.status, 0) << r.output;
  for (const std::string s : {"stack", "pyramid", "pendulum_chain", "chain", "pile", "box_on_ground", "shapes"})
    EXPECT_NE(r.output.find(s), std::string::npos) << s;
  EXPECT_NE(r.output.find("Generators"), std::string::npos);
  EXPECT_EQ(r.output.find("does not load"), std::string::npos) << r.output;
}

// Acceptance of the foundation: under A2 no box of the 5-box stack moves more than 1 cm in 5 s;
// the trajectory has the documented header, --every keeps the first and last steps, and the
// metrics say where the time went.
TEST(Cli, RunWritesTrajectoryAndMetrics) {
  const fs::path traj = scratch("stack.csv"), metrics = scratch("stack.json");
  fs::remove(traj);
  fs::remove(metrics);
  const Outcome r = run("run assets/scenes/stack.json --algo a2 --seconds 5 --every 7 --trajectory " + traj.string() +
                    " --metrics " + metrics.string());
  ASSERT_EQ(r.status, 0) << r.output;
  const auto rows = readCsv(traj);
  ASSERT_GT(rows.size(), 2u);
  EXPECT_EQ(rows[0], (std::vector<std::string>{"step", "time", "body", "px", "py", "pz", "qw", "qx", "qy", "qz", "vx",
                                                "vy", "vz", "wx", "wy", "wz"}));
  std::map<std::string, std::array<double, 3>> start;
  std::set<long> steps;
  double worst = 0;
  for (size_t i = 1; i < rows.size(); ++i) {
    const auto& c = rows[i];
    ASSERT_EQ(c.size(), 16u);
    steps.insert(std::stol(c[0]));
    const std::array<double, 3> p{std::stod(c[3]), std::stod(c[4]), std::stod(c[5])};
    if (!start.count(c[2])) start[c[2]] = p;
    const auto& s = start[c[2]];
    worst = std::max(worst, std::hypot(p[0] - s[0], p[1] - s[1], p[2] - s[2]));
  }
  EXPECT_EQ(start.size(), 5u);  // the dynamic bodies only
  EXPECT_LT(worst, 0.01) << "a box moved " << worst << " m";
  EXPECT_TRUE(steps.count(0));
  EXPECT_TRUE(steps.count(7));
  EXPECT_TRUE(steps.count(300));   // the last, though 300 is not a multiple of 7
  EXPECT_FALSE(steps.count(8));
  std::ifstream in(metrics);
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["steps"], 300);
  EXPECT_TRUE(j["finite"].get<bool>());
  for (const char* k : {"s1_geometry", "s2_formulation", "s3_velocities", "s4_coordinates", "total"})
    EXPECT_GE(j["stage_ms_per_step"][k].get<double>(), 0.0) << k;
  EXPECT_LT(j["violation"]["max_penetration"].get<double>(), 0.01);
  EXPECT_EQ(j["series"]["kinetic"].size(), j["series"]["time"].size());
  EXPECT_GT(j["series"]["potential"][0].get<double>(), 0.0);
  // Nothing half-written is left behind.
  for (const auto& e : fs::directory_iterator(traj.parent_path()))
    EXPECT_EQ(e.path().string().find(".part"), std::string::npos) << e.path();
}

// A failing run leaves no output file and no temporary file.
TEST(Cli, FailedRunLeavesNothingBehind) {
  const fs::path traj = scratch("never.csv");
  fs::remove(traj);
  const Outcome r = run("run assets/scenes/pile.json --algo a1 --steps 200 --trajectory " + traj.string());
  EXPECT_EQ(r.status, 1) << r.output;  // A1 refuses a 1000-box pile: too many rows for a dense solve
  EXPECT_NE(r.output.find("a1 solves the MLCP with a dense"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(traj));
  for (const auto& e : fs::directory_iterator(traj.parent_path()))
    EXPECT_EQ(e.path().filename().string().rfind("never.csv", 0), std::string::npos) << e.path();
}

// A scene that diverges (a 1e-300 kg box thrown at 1e200 m/s onto a 1e300 kg one) stops with
// exit status 3 and a message naming the body; the metrics say it did not stay finite.
TEST(Cli, DivergingRunStopsWithStatus3) {
  const fs::path metrics = scratch("diverging.json");
  fs::remove(metrics);
  const Outcome r = run("run tests/data/diverging.json --seconds 1 --metrics " + metrics.string());
  EXPECT_EQ(r.status, 3) << r.output;
  EXPECT_NE(r.output.find("diverged"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"light\""), std::string::npos) << r.output;
  std::ifstream in(metrics);
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_FALSE(j["finite"].get<bool>());
  EXPECT_NE(j["stopped"].get<std::string>().find("light"), std::string::npos);
}

// Two runs of the same scene in two processes write byte-identical trajectories.
TEST(Cli, RunsAreReproducibleAcrossProcesses) {
  const fs::path a = scratch("det-a.csv"), b = scratch("det-b.csv");
  for (const fs::path& f : {a, b}) {
    const Outcome r = run("run assets/scenes/pendulum_chain.json --seconds 2 -q --trajectory " + f.string());
    ASSERT_EQ(r.status, 0) << r.output;
  }
  std::ifstream fa(a), fb(b);
  const std::string sa((std::istreambuf_iterator<char>(fa)), {}), sb((std::istreambuf_iterator<char>(fb)), {});
  EXPECT_GT(sa.size(), 1000u);
  EXPECT_EQ(sa, sb);
}

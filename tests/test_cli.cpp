// The substep executable: exit statuses, messages, outputs. Runs the built binary.
#include "run_substep.h"

#include "physics/settings.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/stat.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <algorithm>
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
      {"wrong_type.json", {"bodies[0].shape.radius", "expected a number in [0.001, 10000], got string"}},
      {"missing_field.json", {"bodies[0].shape", "missing required field \"half_extents\""}},
      {"misspelt_key.json", {"bodies[0].shape", "unknown key \"radus\""}},
      {"negative_mass.json", {"bodies[0].mass", "expected a number in [1e-6, 1e9], got -2"}},
      {"zero_size.json", {"bodies[0].shape.half_height", "expected a number in [0.001, 10000], got 0"}},
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
  EXPECT_NE(r.output.find("--substeps: a2 does not use it (a3, a4, a5, soft do)"), std::string::npos) << r.output;
  r = run("run assets/scenes/stack.json --steps 10 --seconds 1");
  EXPECT_EQ(r.status, 2);
  r = run("run assets/scenes/stack.json --steps 1 --trajectory /proc/forbidden/t.csv");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("/proc/forbidden"), std::string::npos) << r.output;
  r = run("frobnicate");
  EXPECT_EQ(r.status, 2);
}

// The hostile inputs of tests/data/hostile (each once a crash, a hang or a raw library message):
// exit status 2 with one line naming the file, the JSON path (or line:column) and what was
// expected, in well under the timeout; the plane scene simply runs. The fuzz target starts from
// the same files (tests/fuzz).
TEST(Cli, HostileScenesAreRefusedWithTheirPathQuickly) {
  const std::map<std::string, std::vector<std::string>> cases = {
      {"plane_ground.json", {}},
      {"huge_box.json", {"bodies[0].shape.half_extents[0]", "in [0.001, 10000]", "1e154"}},
      {"huge_gravity.json", {"gravity[1]", "in [-1000, 1000]"}},
      {"huge_capsule.json", {"bodies[1].shape.half_height", "1e308"}},
      {"tilted_cylinder_on_mesh.json", {"bodies[1].shape.half_height", "1e22"}},
      {"far_position.json", {"bodies[0].position[0]", "in [-100000, 100000]"}},
      {"fast_body.json", {"bodies[0].velocity[1]", "in [-10000, 10000]"}},
      {"number_overflow.json", {"number_overflow.json:2:34", "1e999", "finite number"}},
      {"open_convex_mesh.json", {"bodies[0].shape.file", "not a closed surface", "4 edges"}},
      {"stdin_mesh.json", {"bodies[0].shape.file", "not a regular file"}},
      {"nul_in_mesh_path.json", {"bodies[0].shape.file", "NUL character"}},
      {"tiny_dt.json", {"solver.dt", "in [1e-6, 1]", "1e-300"}},
      {"big_kappa.json", {"solver.kappa", "in (0, 10]", "850"}},
      {"pyramid_400.json", {"generators[0].levels", "80200 bodies", "--max-bodies"}},
      {"chains_100000.json", {"generators[0].count", "--max-bodies"}},
      {"overlapping_2000.json", {"initial configuration", "pairs of bodies overlap", "move the bodies apart"}},
  };
  for (const auto& [file, fragments] : cases) {
    const std::string path = "tests/data/hostile/" + file;
    const Outcome r = substep_test::runShell("timeout 60 " SUBSTEP_EXE " run " + path + " --steps 5 -q </dev/null");
    ASSERT_NE(r.status, 124) << file << " ran for a minute";
    EXPECT_EQ(r.status, fragments.empty() ? 0 : 2) << file << ": " << r.output;
    if (fragments.empty()) continue;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;  // one line
    EXPECT_LT(r.output.size(), 500u) << r.output;
    EXPECT_NE(r.output.find(path), std::string::npos) << r.output;
    for (const std::string& f : fragments) EXPECT_NE(r.output.find(f), std::string::npos) << file << ": " << r.output;
  }
  int files = 0;
  for (const auto& e : fs::directory_iterator(SUBSTEP_SOURCE_DIR "/tests/data/hostile")) files += e.path().extension() == ".json";
  EXPECT_EQ(files, static_cast<int>(cases.size()));
}

// Inputs that would block or never end: a FIFO, a terminal or pipe, /dev/zero, as the scene or as
// a mesh; and JSON nested 500 000 deep (once 9 s and a 1 MB message).
TEST(Cli, FilesThatAreNotRegularOrTooDeepAreRefused) {
  const fs::path fifo = scratch("fifo.json");
  fs::remove(fifo);
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  const fs::path meshScene = scratch("fifo_mesh.json");
  std::ofstream(meshScene) << R"({"bodies": [{"name": "b", "shape": {"type": "convex", "file": "fifo.json"}}]})";
  const fs::path deep = scratch("deep.json");
  std::ofstream(deep) << std::string(500000, '[') << std::string(500000, ']');
  const std::vector<std::pair<std::string, std::string>> cases = {
      {fifo.string(), "not a regular file"},   {"/dev/zero", "not a regular file"},
      {"/dev/stdin", "not a regular file"},    {meshScene.string(), "bodies[0].shape.file"},
      {deep.string(), "nested more than 64"},  {"assets", "Is a directory"},
  };
  for (const auto& [file, fragment] : cases) {
    const Outcome r = substep_test::runShell("timeout 20 " SUBSTEP_EXE " run " + file + " -q </dev/null");
    EXPECT_EQ(r.status, 2) << file << ": " << r.output;
    EXPECT_NE(r.output.find(fragment), std::string::npos) << r.output;
    EXPECT_LT(r.output.size(), 500u) << r.output;
  }
  fs::remove(fifo);
}

// Options: non-finite and absurd numbers, empty values and one file named twice are refused
// before any work, with exit status 2 and the option's name.
TEST(Cli, BadOptionValuesAreRefused) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"--seconds nan", "--seconds"},       {"--seconds inf", "--seconds"},
      {"--kappa inf --algo a5", "--kappa"}, {"--kappa 850 --algo a5", "in (0, 10]"},
      {"--dt 1e-300", "--dt"},              {"--tau nan --algo a5", "--tau"},
      {"--preset ''", "--preset"},          {"--algo ''", "--algo"},
      {"--trajectory ''", "--trajectory"},  {"--metrics ''", "--metrics"},
      {"--substeps 2.5 --algo a5", "--substeps"},
      {"--trajectory same.csv --metrics ./same.csv", "name the same file"},
      {"--max-bodies 0", "--max-bodies"},   {"--max-bodies 3", "limit of 3 bodies"},
  };
  for (const auto& [args, fragment] : cases) {
    const Outcome r = substep_test::runShell("cd " + scratch("").string() + " && " SUBSTEP_EXE " run " SUBSTEP_SOURCE_DIR
                                             "/assets/scenes/stack.json --steps 2 " + args);
    EXPECT_EQ(r.status, 2) << args << ": " << r.output;
    EXPECT_NE(r.output.find(fragment), std::string::npos) << args << ": " << r.output;
  }
  EXPECT_FALSE(fs::exists(scratch("same.csv")));
}

// Each setting of the table is an option of `run` (and `render`), refused outside its range with
// the same words a scene file's solver block gets (test_scene_file.cpp).
TEST(Cli, SolverOptionsUseTheTable) {
  const std::string help = run("run --help").output;
  for (const substep::SettingSpec& spec : substep::settingTable()) {
    EXPECT_NE(help.find(std::string("--") + spec.flag), std::string::npos) << spec.flag;
    if (spec.kind == substep::SettingKind::Flag) {
      EXPECT_NE(help.find(std::string("--no-") + spec.flag), std::string::npos) << spec.flag;
      continue;
    }
    const std::string bad = spec.kind == substep::SettingKind::Choice ? "nonsense" : "1e999";
    const std::string algo = std::string(spec.key) == "algorithm" ? "" : " --algo a5";
    const Outcome r = run("run assets/scenes/stack.json --steps 1" + algo + " --" + std::string(spec.flag) + " " + bad);
    EXPECT_EQ(r.status, 2) << spec.flag << ": " << r.output;
    EXPECT_NE(r.output.find(std::string("--") + spec.flag + ": expected " + spec.expected() + ", got \"" + bad + "\""),
              std::string::npos)
        << r.output;
  }
}

// docs/settings.md's table is the schema's own output, not a second list to keep in step.
TEST(Cli, SettingsDocIsTheSchema) {
  const Outcome r = run("settings --format markdown");
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream in(SUBSTEP_SOURCE_DIR "/docs/settings.md");
  std::stringstream doc;
  doc << in.rdbuf();
  const std::string d = doc.str(), open = "<!-- substep settings --format markdown -->\n", close = "<!-- end -->";
  const size_t a = d.find(open), b = d.find(close);
  ASSERT_TRUE(a != std::string::npos && b != std::string::npos) << "docs/settings.md lacks its markers";
  EXPECT_EQ(d.substr(a + open.size(), b - a - open.size()), r.output)
      << "docs/settings.md differs from the schema: write the block again with substep settings --format markdown";
  for (const substep::SettingSpec& spec : substep::settingTable())
    EXPECT_NE(r.output.find(std::string("| `") + spec.key + "` |"), std::string::npos) << spec.key;
}

// The run's metrics JSON holds every resolved setting, by the schema's keys.
TEST(Cli, RunMetricsHoldEverySetting) {
  const fs::path m = scratch("every.json");
  ASSERT_EQ(run("run assets/scenes/chain.json --algo soft --steps 2 -q --metrics " + m.string()).status, 0);
  std::ifstream in(m);
  const nlohmann::json j = nlohmann::json::parse(in);
  for (const substep::SettingSpec& spec : substep::settingTable())
    EXPECT_EQ(j["settings"].contains(spec.key), spec.resolved()) << spec.key;
  EXPECT_EQ(j["settings"]["algorithm"], "soft");
  EXPECT_EQ(j["settings"]["contact_hertz"], 30);
}

// Ctrl-C during a run: exit status 130, a message, no temporary left; and a temporary left by a
// process that is gone (killed with SIGKILL) is removed by the next run writing the same file.
TEST(Cli, InterruptedRunLeavesNoTemporary) {
  const fs::path traj = scratch("t.csv");
  fs::remove(traj);
  const Outcome r = substep_test::runShell("(" SUBSTEP_EXE " run assets/scenes/pyramid.json --seconds 600 -q --trajectory " +
                                           traj.string() + " & pid=$!; sleep 1; kill -INT $pid; wait $pid)");
  EXPECT_EQ(r.status, 130) << r.output;
  EXPECT_NE(r.output.find("interrupted at step"), std::string::npos) << r.output;
  for (const auto& e : fs::directory_iterator(traj.parent_path())) ADD_FAILURE() << "left behind: " << e.path();
  // A stale temporary of a process that no longer exists (pid 2^22 + 1 is beyond Linux's pid_max).
  const fs::path stale = traj.string() + ".part4194305";
  std::ofstream(stale) << "step,time\n";
  EXPECT_EQ(run("run assets/scenes/stack.json --steps 2 -q --trajectory " + traj.string()).status, 0);
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(traj));
}

// The progress bar is drawn on a terminal only, and -q silences it there too.
TEST(Cli, ProgressBarOnlyOnATerminalAndNotWithQuiet) {
  // runSubstepOnTerminal draws the bar from the start ($SUBSTEP_PROGRESS_DELAY=0): a short run will do.
  const std::string args = "run assets/scenes/pyramid.json --seconds 2";
  Outcome r = substep_test::runSubstepOnTerminal(args);
  EXPECT_NE(r.output.find("run ["), std::string::npos) << r.output;
  r = substep_test::runSubstepOnTerminal(args + " -q");
  EXPECT_EQ(r.output.find("run ["), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("stepped"), std::string::npos) << r.output;
  r = run(args);
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output.find("run ["), std::string::npos) << r.output;
}

// A1's work per step is bounded (Lemke stops after kLemkePivotsPerVariable pivots per variable):
// the mass-ratio chain, once 34 s for 120 steps, runs through the steps where Lemke ends on rays,
// and the metrics count which of A1's solvers answered each step.
TEST(Cli, DirectSolverFallbacksAreCountedInTheMetrics) {
  const fs::path m = scratch("m.json");
  const Outcome r = run("run assets/scenes/mass_ratio.json --algo a1 --steps 90 --metrics " + m.string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("by Lemke"), std::string::npos) << r.output;
  std::ifstream in(m);
  const nlohmann::json j = nlohmann::json::parse(in);
  const auto& d = j["solver"]["direct_method_steps"];
  const long long dantzig = d["dantzig"], lemke = d["lemke"], gs = d["gauss_seidel"];
  EXPECT_EQ(dantzig + lemke + gs, 90);
  EXPECT_GT(dantzig, 0);
  EXPECT_GT(gs, 0);  // the steps where Lemke stops on a ray or at its cap
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

// A failing run leaves no output file and no temporary file. A1 refusing the pyramid (too many rows
// for a dense solve) is bad input, settings the scene cannot take: exit status 2.
TEST(Cli, FailedRunLeavesNothingBehind) {
  const fs::path traj = scratch("never.csv");
  fs::remove(traj);
  const Outcome r = run("run assets/scenes/pyramid.json --algo a1 --steps 200 --trajectory " + traj.string());
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("a1 solves the MLCP with a dense"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(traj));
  for (const auto& e : fs::directory_iterator(traj.parent_path()))
    EXPECT_EQ(e.path().filename().string().rfind("never.csv", 0), std::string::npos) << e.path();
}

// A scene that diverges (a pendulum whose joint error a3 at τ = 10 amplifies ninefold a sub-step)
// stops with exit status 3 and a message naming the body; the metrics say it did not stay finite.
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

// The lab's commands (substep sweep, sweep merge, chart, advise, atlas) as a user runs them: the
// built binary, its outputs, exit statuses and messages; the sweep spread with GNU parallel and
// as a Slurm job array (its script's body, run here with the array's variables set).
#include "run_substep.h"

#include "render/image.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <cmath>
#include <fstream>
#include <random>
#include <set>
#include <sstream>

namespace fs = std::filesystem;
using substep_test::Outcome;
using nlohmann::json;

namespace {

Outcome run(const std::string& args) { return substep_test::runSubstep(args); }

fs::path folder() { return substep_test::emptyScratchFolder("test_lab_cli_out"); }

std::vector<json> rows(const fs::path& f) {
  std::vector<json> out;
  std::ifstream in(f);
  std::string line;
  while (std::getline(in, line))
    if (!line.empty()) out.push_back(json::parse(line));
  return out;
}

std::set<std::string> keys(const fs::path& f) {
  std::set<std::string> k;
  for (const json& r : rows(f)) k.insert(r["key"].get<std::string>());
  return k;
}

// A small sweep spec: two cheap scenes, a grid of methods, one second each.
fs::path smallSpec(const fs::path& dir) {
  const fs::path spec = dir / "spec.json";
  std::ofstream(spec) << R"({"scenes": ["pendulum_chain", "atlas/projectile_wall"], "methods": ["a2:m=4|10", "a5:n=2|4:m=1"],
                             "seconds": 0.5})";
  return spec;
}

// A chart as gnuplot drew it: a PNG of the size asked for with more than a few colours (not
// blank), and its SVG beside it naming every series it should. A Pareto chart grows below its
// 600 px by the list of the points whose labels did not fit, and only then: which points those
// are depends on the measured costs, so either size is right when it matches the list.
void expectChart(const fs::path& png, const std::vector<std::string>& series) {
  SCOPED_TRACE(png.string());
  ASSERT_TRUE(fs::exists(png));
  const substep::render::Image img = substep::render::readPng(png.string());
  fs::path svgPath = png;
  svgPath.replace_extension(".svg");
  std::ifstream svg(svgPath);
  std::stringstream text;
  text << svg.rdbuf();
  EXPECT_NE(text.str().find("<svg"), std::string::npos);
  const bool listed = text.str().find("Not labelled on the chart") != std::string::npos;
  EXPECT_EQ(img.width, 960);
  if (listed)
    EXPECT_GT(img.height, 600);
  else
    EXPECT_EQ(img.height, 600);
  std::set<uint32_t> colours;
  for (size_t i = 0; i + 3 < img.rgba.size(); i += 4 * 97)
    colours.insert(uint32_t(img.rgba[i]) << 16 | uint32_t(img.rgba[i + 1]) << 8 | img.rgba[i + 2]);
  EXPECT_GT(colours.size(), 3u) << "the chart is blank";
  for (const std::string& s : series) EXPECT_NE(text.str().find(">" + s + "<"), std::string::npos) << s;
}

// What a terminal shows of an output with carriage returns: each line as it is left after the
// returns overwrite it.
std::vector<std::string> screenLines(const std::string& out) {
  std::vector<std::string> lines;
  std::string line;
  size_t col = 0;
  for (char c : out) {
    if (c == '\n') {
      lines.push_back(line);
      line.clear();
      col = 0;
    } else if (c == '\r') {
      col = 0;
    } else {
      if (col < line.size())
        line[col] = c;
      else
        line += c;
      ++col;
    }
  }
  if (!line.empty()) lines.push_back(line);
  return lines;
}

}  // namespace

// Acceptance: `substep sweep --scenes chain --methods a2:m=4,a5:n=4 --repeat 1 -o s.jsonl` writes
// two rows, and `substep chart s.jsonl -o charts/` draws from them: a PNG of the expected size,
// not blank, and its SVG.
TEST(Sweep, TwoRowsAndAChartDrawnFromThem) {
  const fs::path d = folder();
  const Outcome s = run("sweep --scenes chain --methods a2:m=4,a5:n=4 --repeat 1 -o " + (d / "s.jsonl").string());
  ASSERT_EQ(s.status, 0) << s.output;
  EXPECT_NE(s.output.find("2 runs (1 scene x 2 methods x 1 time step)"), std::string::npos) << s.output;
  const std::vector<json> r = rows(d / "s.jsonl");
  ASSERT_EQ(r.size(), 2u);
  EXPECT_EQ(r[0]["method"], "a2:m=4");
  EXPECT_EQ(r[1]["method"], "a5:n=4");
  for (const json& x : r) {
    EXPECT_TRUE(x["finite"].get<bool>());
    EXPECT_GT(x["cost"]["ms_per_step"].get<double>(), 0);
    EXPECT_TRUE(x["values"].contains("joint_error"));
    EXPECT_FALSE(x["commit"].get<std::string>().empty());
  }
  const Outcome c = run("chart " + (d / "s.jsonl").string() + " -o " + (d / "charts/").string());
  ASSERT_EQ(c.status, 0) << c.output;
  EXPECT_NE(c.output.find("Pareto front"), std::string::npos) << c.output;
  expectChart(d / "charts" / "chain-pareto.png", {"a2", "a5", "Pareto front"});  // every method in the legend
  EXPECT_TRUE(fs::exists(d / "charts" / "data" / "chain-pareto.gp"));
  EXPECT_TRUE(fs::exists(d / "charts" / "data" / "chain-pareto.dat"));
  for (const auto& e : fs::directory_iterator(d / "charts"))
    EXPECT_EQ(e.path().string().find(".part"), std::string::npos) << "left behind: " << e.path();
}

// Every kind of chart from one small sweep: error against cost with the front, sub-steps against
// iterations, A3/A4/A5 against n, and the convergence order; each a PNG and an SVG that name
// every series, the gnuplot data and script kept beside them.
TEST(Chart, EveryKindDrawnFromASweep) {
  const fs::path d = folder();
  const Outcome s = run("sweep --scenes pendulum_chain --methods 'a1:h=1/60|1/120,a2:m=1|2|4,a3:n=1|2|4:m=1,a5:n=1|2|4:m=1,bullet' "
                        "--seconds 0.5 -q -o " + (d / "s.jsonl").string());
  ASSERT_EQ(s.status, 0) << s.output;
  ASSERT_EQ(rows(d / "s.jsonl").size(), 12u);
  const Outcome c = run("chart " + (d / "s.jsonl").string() + " -o " + (d / "charts").string());
  ASSERT_EQ(c.status, 0) << c.output;
  EXPECT_NE(c.output.find("wrote     10 files"), std::string::npos) << c.output;
  expectChart(d / "charts" / "pendulum_chain-pareto.png", {"a1", "a2", "a3", "a5", "bullet", "Pareto front"});
  expectChart(d / "charts" / "pendulum_chain-substeps.png",
              {"a2: 1 step of n iterations", "a3: n sub-steps of 1 iteration", "a5: n sub-steps of 1 iteration"});
  expectChart(d / "charts" / "pendulum_chain-havok.png", {"a3", "a5"});
  expectChart(d / "charts" / "pendulum_chain-convergence.png", {});
  expectChart(d / "charts" / "pendulum_chain-speed.png", {});  // a1's curve over its two h
  EXPECT_NE(c.output.find("a1 (slope "), std::string::npos) << c.output;  // the fitted order, printed
  for (const char* kind : {"pareto", "substeps", "havok", "convergence"}) {
    EXPECT_GT(fs::file_size(d / "charts" / "data" / ("pendulum_chain-" + std::string(kind) + ".dat")), 0u) << kind;
    EXPECT_GT(fs::file_size(d / "charts" / "data" / ("pendulum_chain-" + std::string(kind) + ".gp")), 0u) << kind;
  }
  // The kept script redraws its chart from the folder.
  fs::remove(d / "charts" / "pendulum_chain-havok.png");
  const Outcome again = substep_test::runShell("cd " + (d / "charts").string() + " && gnuplot data/pendulum_chain-havok.gp");
  EXPECT_EQ(again.status, 0) << again.output;
  expectChart(d / "charts" / "pendulum_chain-havok.png", {"a3", "a5"});
}

// On a terminal the progress bar (runs done, time left) shares the screen with a line per run:
// each run's line starts its own line, the bar never left in front of it.
TEST(Sweep, ProgressBarOnATerminal) {
  const fs::path d = folder();
  const Outcome s = substep_test::runSubstepOnTerminal("sweep --scenes pyramid --methods a2:m=2,a2:m=4,a2:m=6,a2:m=8,a5:n=1,a5:n=2 --seconds 2 -o " +
                                                       (d / "s.jsonl").string());
  ASSERT_EQ(s.status, 0) << s.output;
  EXPECT_NE(s.output.find("s left"), std::string::npos) << s.output;  // the bar was drawn
  EXPECT_NE(s.output.find("sweep done: 6 in"), std::string::npos) << s.output;
  int runLines = 0;
  for (const std::string& line : screenLines(s.output)) {
    const size_t at = line.find("] pyramid  ");
    if (at == std::string::npos) continue;
    ++runLines;
    EXPECT_EQ(line[0], '[') << "a run's line behind the bar: " << line;
  }
  EXPECT_EQ(runLines, 6);
}

// A stopped sweep resumes: the runs in its output are skipped, and a last line cut short (a
// sweep killed while writing it) is removed first.
TEST(Sweep, ResumesFromItsOutput) {
  const fs::path d = folder();
  const fs::path spec = smallSpec(d), out = d / "out.jsonl";
  ASSERT_EQ(run("sweep " + spec.string() + " -o " + out.string() + " -q").status, 0);
  const std::set<std::string> all = keys(out);
  EXPECT_EQ(all.size(), 8u);  // 2 scenes x 4 methods
  Outcome again = run("sweep " + spec.string() + " -o " + out.string());
  EXPECT_EQ(again.status, 0) << again.output;
  EXPECT_NE(again.output.find("8 already in"), std::string::npos) << again.output;
  EXPECT_NE(again.output.find("0 to run"), std::string::npos) << again.output;
  // Keep the first five rows and half of the sixth.
  std::vector<std::string> lines;
  {
    std::ifstream in(out);
    for (std::string l; std::getline(in, l);) lines.push_back(l);
  }
  {
    std::ofstream o(out, std::ios::trunc);
    for (int i = 0; i < 5; ++i) o << lines[static_cast<size_t>(i)] << "\n";
    o << lines[5].substr(0, lines[5].size() / 2);
  }
  again = run("sweep " + spec.string() + " -o " + out.string());
  EXPECT_EQ(again.status, 0) << again.output;
  EXPECT_NE(again.output.find("5 already in"), std::string::npos) << again.output;
  EXPECT_EQ(keys(out), all);
  EXPECT_EQ(rows(out).size(), 8u);
}

// Shards run every N-th run; merging them gives the whole sweep, and says what is missing or
// twice.
TEST(Sweep, ShardsMergeAndGapsAreNamed) {
  const fs::path d = folder();
  const fs::path spec = smallSpec(d);
  ASSERT_EQ(run("sweep " + spec.string() + " -o " + (d / "all.jsonl").string() + " -q").status, 0);
  for (int i = 1; i <= 3; ++i)
    ASSERT_EQ(run("sweep " + spec.string() + " --shard " + std::to_string(i) + "/3 -o " + (d / ("s" + std::to_string(i) + ".jsonl")).string() + " -q").status, 0);
  EXPECT_EQ(rows(d / "s1.jsonl").size(), 3u);  // runs 1, 4, 7 of 8
  EXPECT_EQ(rows(d / "s3.jsonl").size(), 2u);
  Outcome m = run("sweep merge " + (d / "s1.jsonl").string() + " " + (d / "s2.jsonl").string() + " " + (d / "s3.jsonl").string() +
                  " -o " + (d / "merged.jsonl").string());
  ASSERT_EQ(m.status, 0) << m.output;
  EXPECT_EQ(keys(d / "merged.jsonl"), keys(d / "all.jsonl"));
  // A missing shard: not written, and the missing runs named.
  m = run("sweep merge " + (d / "s1.jsonl").string() + " " + (d / "s3.jsonl").string() + " -o " + (d / "gap.jsonl").string());
  EXPECT_EQ(m.status, 1);
  EXPECT_NE(m.output.find("3 of 8 runs missing (2, 5, 8)"), std::string::npos) << m.output;
  EXPECT_FALSE(fs::exists(d / "gap.jsonl"));
  m = run("sweep merge --allow-gaps " + (d / "s1.jsonl").string() + " " + (d / "s3.jsonl").string() + " -o " + (d / "gap.jsonl").string());
  EXPECT_EQ(m.status, 0) << m.output;
  EXPECT_EQ(rows(d / "gap.jsonl").size(), 5u);
  // A shard given twice: each run kept once, the duplicates named.
  m = run("sweep merge " + (d / "all.jsonl").string() + " " + (d / "s2.jsonl").string() + " -o " + (d / "dup.jsonl").string());
  EXPECT_EQ(m.status, 0) << m.output;
  EXPECT_NE(m.output.find("duplicate run (kept the first)"), std::string::npos) << m.output;
  EXPECT_EQ(rows(d / "dup.jsonl").size(), 8u);
}

// The README's recipe on one machine: GNU parallel runs the shards, two at a time.
TEST(Sweep, SpreadWithGnuParallel) {
  const fs::path d = folder();
  const fs::path spec = smallSpec(d);
  const Outcome p = substep_test::runShell("parallel --will-cite -j 2 " SUBSTEP_EXE " sweep " + spec.string() +
                                           " --shard {}/4 -o " + d.string() + "/shard-{}.jsonl -q ::: 1 2 3 4");
  ASSERT_EQ(p.status, 0) << p.output;
  const Outcome m = run("sweep merge " + d.string() + "/shard-1.jsonl " + d.string() + "/shard-2.jsonl " + d.string() +
                        "/shard-3.jsonl " + d.string() + "/shard-4.jsonl -o " + (d / "all.jsonl").string());
  ASSERT_EQ(m.status, 0) << m.output;
  EXPECT_EQ(keys(d / "all.jsonl").size(), 8u);
}

// The Slurm job array's script, its body run here as each array task would run it.
TEST(Sweep, SlurmArrayScriptBody) {
  const fs::path d = folder();
  const fs::path spec = smallSpec(d);
  for (int task = 0; task < 2; ++task) {  // an array 0-1: tasks count from SLURM_ARRAY_TASK_MIN
    const Outcome t = substep_test::runShell("SLURM_ARRAY_TASK_ID=" + std::to_string(task) +
                                             " SLURM_ARRAY_TASK_MIN=0 SLURM_ARRAY_TASK_COUNT=2 SUBSTEP=" SUBSTEP_EXE
                                             " bash scripts/sweep-slurm.sh " + spec.string() + " " + (d / "out").string());
    ASSERT_EQ(t.status, 0) << t.output;
  }
  const Outcome m = run("sweep merge " + (d / "out" / "shard-1.jsonl").string() + " " + (d / "out" / "shard-2.jsonl").string() +
                        " -o " + (d / "all.jsonl").string());
  ASSERT_EQ(m.status, 0) << m.output;
  EXPECT_EQ(keys(d / "all.jsonl").size(), 8u);
  // Outside Slurm it says what is missing.
  const Outcome bare = substep_test::runShell("bash scripts/sweep-slurm.sh " + spec.string() + " " + (d / "x").string());
  EXPECT_NE(bare.status, 0);
  EXPECT_NE(bare.output.find("not in a Slurm job array"), std::string::npos) << bare.output;
  std::ifstream script(SUBSTEP_SOURCE_DIR "/scripts/sweep-slurm.sh");
  std::stringstream text;
  text << script.rdbuf();
  EXPECT_NE(text.str().find("#SBATCH --array="), std::string::npos);
}

// A run that diverges is a row that says so, not an abort; a method that cannot run a scene too.
TEST(Sweep, DivergedAndRefusedRunsAreRows) {
  const fs::path d = folder();
  // tests/data/diverging.json: a pendulum whose joint error grows ninefold a sub-step under a3 at
  // tau = 10 (its own solver block, which a sweep's methods do not take: the method names it).
  const Outcome s = run("sweep --scenes tests/data/diverging.json,shapes --methods a3:tau=10,bullet -o " + (d / "s.jsonl").string());
  ASSERT_EQ(s.status, 0) << s.output;
  const std::vector<json> r = rows(d / "s.jsonl");
  ASSERT_EQ(r.size(), 4u);
  EXPECT_EQ(r[0]["method"], "a3:tau=10");
  EXPECT_TRUE(r[0]["diverged"].get<bool>());
  ASSERT_TRUE(r[0]["stopped"].is_string()) << r[0].dump();
  EXPECT_NE(r[0]["stopped"].get<std::string>().find("the simulation diverged at step "), std::string::npos);
  EXPECT_FALSE(r[0].contains("verdict"));  // the fixture states no criteria: no verdict
  EXPECT_LT(r[0]["steps_done"].get<long long>(), r[0]["steps"].get<long long>());
  EXPECT_FALSE(r[1]["diverged"].get<bool>());  // Bullet on the same pendulum: the sweep went on
  EXPECT_TRUE(r[3]["refused"].get<bool>());    // Bullet has no meshes
  EXPECT_NE(s.output.find("DIVERGED"), std::string::npos) << s.output;
  EXPECT_NE(s.output.find("refused: no Bullet peer"), std::string::npos) << s.output;
}

// Bad input: exit status 2 and a message naming what was wrong.
TEST(Sweep, BadInputIsNamed) {
  const fs::path d = folder();
  const std::string out = " -o " + (d / "x.jsonl").string();
  struct Case {
    std::string args, says;
  };
  for (const Case& c : std::vector<Case>{
           {"sweep --scenes chain --methods a9" + out, "--methods: \"a9\": unknown algorithm"},
           {"sweep --scenes chain --methods a2 --dt 1/0" + out, "--dt: expected a number in [1e-6, 1]"},
           {"sweep --scenes chain --methods a2 --shard 5/4" + out, "--shard: expected i/N"},
           {"sweep --scenes nowhere --methods a2" + out, "nowhere.json: cannot open"},
           {"sweep --methods a2" + out, "no scenes"},
           {"sweep --scenes chain --methods a2:preset=4-medium" + out, "a2:preset=4-medium\": preset: presets set"},
           {"sweep --scenes chain --methods bullet:kappa=1" + out, "the Bullet peer takes h, it and gyro"},
           {"chart " + (d / "none.jsonl").string() + " -o " + d.string(), "cannot open"},
           {"chart assets/scenes/chain.json -o " + d.string(), "not a JSON record"},
           {"advise assets/scenes/chain.json", "give a target"},
           {"advise assets/scenes/chain.json --max-joint-error 1parsec", "--max-joint-error: expected a length"},
           {"advise assets/scenes/stack.json --max-joint-error 1cm", "has no joints"},
           {"atlas -o " + d.string() + " --methods a7", "--methods: \"a7\""},
       }) {
    const Outcome r = run(c.args);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.says), std::string::npos) << c.args << "\n" << r.output;
  }
  // A bad spec file: the file, the field and what was expected.
  for (const Case& c : std::vector<Case>{
           {R"({"scenes": ["chain"], "methods": ["a2"], "repeats": 3})", "spec.json: unknown key \"repeats\""},
           {R"({"scenes": ["chain"], "methods": ["a2:m=0"]})", "spec.json: methods[0]: \"a2:m=0\": m: expected an integer in [1, 100000], got \"0\""},
           {R"({"scenes": ["chain"], "methods": ["a2"], "repeat": "three"})", "spec.json: repeat: expected an integer in [1, 1000]"},
           {R"({"scenes": ["chain"], "methods": ["a2"], "dt": ["1/0"]})", "spec.json: dt[0]: expected a number in [1e-6, 1]"},
           {R"({"scenes": ["chain", 3], "methods": ["a2"]})", "spec.json: scenes[1]: expected a string"},
           {R"({"scenes": ["chain"], "methods": ["a2"], "reference": {"type": "pendulum"}})",
            "chain.json (with the sweep's reference): criteria.reference: missing required field \"body\""},
           {R"({"scenes": ["chain"], "methods": ["a2"], )", "spec.json: not JSON"},
       }) {
    std::ofstream(d / "spec.json") << c.args;
    const Outcome r = run("sweep " + (d / "spec.json").string() + out);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.says), std::string::npos) << c.args << "\n" << r.output;
  }
  EXPECT_FALSE(fs::exists(d / "x.jsonl"));  // nothing written
}

// Ctrl-C: exit status 130; the rows written before it stay whole, and the next sweep resumes.
TEST(Sweep, InterruptKeepsWholeRows) {
  const fs::path d = folder();
  const fs::path out = d / "s.jsonl";
  const Outcome r = substep_test::runShell("(" SUBSTEP_EXE " sweep --scenes pendulum_chain,atlas/pyramid_40 --methods a2:m=4,a5 "
                                           "--seconds 30 -q -o " + out.string() + " & pid=$!; sleep 2; kill -INT $pid; wait $pid)");
  EXPECT_EQ(r.status, 130) << r.output;
  EXPECT_NE(r.output.find("interrupted"), std::string::npos) << r.output;
  const std::vector<json> done = rows(out);  // every line parses
  EXPECT_LT(done.size(), 4u);
  for (const auto& e : fs::directory_iterator(d)) EXPECT_EQ(e.path().string().find(".part"), std::string::npos) << e.path();
}

// Acceptance: advice for the chain at 1 cm of joint error prints a setting, and running that
// setting with `substep run` meets the target.
TEST(Advise, TheAdvisedRunMeetsTheTarget) {
  const fs::path d = folder();
  const Outcome a = run("advise assets/scenes/chain.json --max-joint-error 1cm --json");
  ASSERT_EQ(a.status, 0) << a.output;
  const json j = json::parse(a.output);
  ASSERT_TRUE(j["met"].get<bool>());
  const std::string line = j["best"]["run"].get<std::string>();
  EXPECT_EQ(line.rfind("substep run assets/scenes/chain.json", 0), 0u) << line;
  EXPECT_LE(j["best"]["value"].get<double>(), 0.01);
  EXPECT_GE(j["best"]["margin"].get<double>(), 0);
  EXPECT_TRUE(j["runner_up"].is_object());
  EXPECT_GE(j["runner_up_cost_ratio"].get<double>(), 1);
  const Outcome r = run(line.substr(std::string("substep ").size()) + " -q --metrics " + (d / "m.json").string());
  ASSERT_EQ(r.status, 0) << line << "\n" << r.output;
  std::ifstream in(d / "m.json");
  const json m = json::parse(in);
  EXPECT_LE(m["violation"]["max_joint_error"].get<double>(), 0.01) << line;
  // The text form says the same.
  const Outcome t = run("advise assets/scenes/chain.json --max-joint-error 1cm");
  EXPECT_EQ(t.status, 0) << t.output;
  for (const char* w : {"best ", "runner-up ", "under the target", "run it    substep run assets/scenes/chain.json"})
    EXPECT_NE(t.output.find(w), std::string::npos) << w << "\n" << t.output;
}

TEST(Advise, SaysWhenNothingMeetsTheTarget) {
  const Outcome a = run("advise assets/scenes/chain.json --max-joint-error 1um --methods 'a2:m=4|10' --repeat 1");
  EXPECT_EQ(a.status, 1) << a.output;
  EXPECT_NE(a.output.find("nothing   in the searched space meets max joint error <= 0.001 mm; the closest was a2:m=10"),
            std::string::npos)
      << a.output;
}

// A scene that states its own criteria is advised on them without a flag, as the atlas judges
// it: the plank bridge (every joint within 2 cm), whose printed line then passes.
TEST(Advise, TheScenesOwnCriteriaAreTheDefaultTarget) {
  const fs::path d = folder();
  const Outcome a = run("advise assets/scenes/atlas/plank_bridge.json");
  ASSERT_EQ(a.status, 0) << a.output;
  EXPECT_NE(a.output.find("target    passes the scene's criteria: max joint error <= 2.00 cm"), std::string::npos) << a.output;
  const size_t at = a.output.find("run it    substep run ");
  ASSERT_NE(at, std::string::npos) << a.output;
  const std::string line = a.output.substr(at + 18, a.output.find('\n', at) - at - 18);
  const Outcome r = run(line + " -q --metrics " + (d / "m.json").string());
  ASSERT_EQ(r.status, 0) << line << "\n" << r.output;
  std::ifstream in(d / "m.json");
  EXPECT_LE(json::parse(in)["violation"]["max_joint_error"].get<double>(), 0.02) << line;
  // A scene without criteria needs a target, and says so.
  const Outcome none = run("advise assets/scenes/stack.json");
  EXPECT_EQ(none.status, 2) << none.output;
  EXPECT_NE(none.output.find("has no criteria of its own to pass"), std::string::npos) << none.output;
}

// A budget that runs out says what it left, cheapest first, and how to widen it; and "nothing"
// then is "nothing run within the budget", not "nothing in the space".
TEST(Advise, ABudgetThatRunsOutSaysWhatItLeft) {
  const Outcome a = run("advise assets/scenes/chain.json --max-joint-error 1cm --max-runs 3");
  EXPECT_EQ(a.status, 1) << a.output;
  EXPECT_NE(a.output.find("searched  3 of 920 settings in "), std::string::npos) << a.output;
  EXPECT_NE(a.output.find("not run   917 settings not run when the budget (3 runs) ran out, the cheapest a5:n=1:m=1:h=1/30:"),
            std::string::npos)
      << a.output;
  EXPECT_NE(a.output.find("; search them with --max-runs 0\n"), std::string::npos) << a.output;
  EXPECT_NE(a.output.find("nothing   run within the budget meets max joint error <= 1.00 cm"), std::string::npos) << a.output;
  const Outcome j = run("advise assets/scenes/chain.json --max-joint-error 1cm --max-runs 3 --json");
  EXPECT_EQ(j.status, 1) << j.output;
  const json r = json::parse(j.output);
  EXPECT_EQ(r["not_run"], 917);
  EXPECT_TRUE(r["budget_spent"].get<bool>());
  EXPECT_GT(r["search_seconds"].get<double>(), 0);
  for (const char* bad : {"--budget 0s", "--budget 5m", "--budget soon"}) {
    const Outcome b = run(std::string("advise assets/scenes/chain.json --max-joint-error 1cm ") + bad);
    EXPECT_EQ(b.status, 2) << bad << b.output;
    EXPECT_NE(b.output.find("--budget: expected a time such as 60s"), std::string::npos) << bad << b.output;
  }
}

namespace {

// A chain of `links` capsules on ball joints from the scene generator, its sizes and direction
// drawn from `seed`, with no criteria: a scene no sweep or test of the repository uses.
fs::path generatedChain(const fs::path& dir, unsigned seed, int* links) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  *links = 8 + static_cast<int>(rng() % 13);
  const double radius = 0.015 + 0.02 * u(rng), half = 0.02 + 0.04 * u(rng), spacing = 2 * (radius + half) + 0.01 * u(rng);
  const double angle = 2 * M_PI * u(rng), drop = -0.5 * u(rng);  // released near horizontal, any heading
  json scene = {{"description", "generated chain, seed " + std::to_string(seed)},
                {"bodies", json::array({{{"name", "ground"}, {"static", true}, {"shape", {{"type", "box"}, {"half_extents", {10, 0.5, 10}}}},
                                          {"position", {0, -0.5, 0}}}})},
                {"generators", json::array({{{"type", "chain"}, {"name", "link"}, {"count", *links},
                                             {"link", {{"type", "capsule"}, {"radius", radius}, {"half_height", half}}},
                                             {"anchor", {0, 5, 0}}, {"direction", {std::cos(angle), drop, std::sin(angle)}},
                                             {"spacing", spacing}, {"mass", 0.2 + u(rng)}, {"friction", 0.5}}})}};
  const fs::path f = dir / ("chain_" + std::to_string(seed) + ".json");
  std::ofstream(f) << scene.dump(1);
  return f;
}

double jointErrorOf(const std::string& runArgs, const fs::path& metrics) {
  const Outcome r = run(runArgs + " -q --metrics " + metrics.string());
  EXPECT_EQ(r.status, 0) << runArgs << "\n" << r.output;
  std::ifstream in(metrics);
  return json::parse(in)["violation"]["max_joint_error"].get<double>();
}

}  // namespace

// A user's own scene: a seeded generated chain. One setting of advise's space is run first and
// its joint error, with room, is the target, so an answer is known to exist; advise with its
// defaults but the budget must find one, and its printed line must meet the target. The budget is
// 30 min, not the default minute: the search takes about a second here, but a loaded CI machine (a
// sanitizer build) must not turn a slow run into a failure; a search that never ends still would.
TEST(Advise, FindsTheAnswerThatExistsOnAGeneratedChain) {
  const fs::path d = folder();
  int links = 0;
  const fs::path scene = generatedChain(d, 20261203, &links);
  const double known = jointErrorOf("run " + scene.string() + " --algo a3 --dt 1/120 --substeps 8 --iterations 4 --kappa 1 --tau 0.6 "
                                    "--no-warm-start --seconds 5", d / "known.json");
  ASSERT_GT(known, 0);
  const double target = 1.2 * known;
  char text[32];
  std::snprintf(text, sizeof text, "%.6fm", target);
  const Outcome a = run("advise " + scene.string() + " --max-joint-error " + text + " --budget 30min --json");
  ASSERT_EQ(a.status, 0) << links << " links, target " << text << "\n" << a.output;
  const json j = json::parse(a.output);
  EXPECT_FALSE(j["budget_spent"].get<bool>()) << a.output;  // the search ended on its own, not on the budget
  const std::string line = j["best"]["run"].get<std::string>();
  EXPECT_LE(jointErrorOf(line.substr(std::string("substep ").size()), d / "best.json"), target) << line;
}

// --max-error on a scene that states no error: the trajectory against a converged reference
// advise computes first, and says which and what it cost.
TEST(Advise, ComputesAndNamesAConvergedReferenceWhenTheSceneHasNone) {
  const fs::path d = folder();
  int links = 0;
  const fs::path scene = generatedChain(d, 5, &links);
  const Outcome a = run("advise " + scene.string() + " --max-error 5cm --seconds 1 --methods 'a5:n=2|8:m=2:h=1/60' --repeat 1");
  EXPECT_EQ(a.status, 0) << a.output;
  EXPECT_NE(a.output.find("reference a1:h=1/480 (halving h moved it "), std::string::npos) << a.output;
  EXPECT_NE(a.output.find(" of the motion), computed in "), std::string::npos) << a.output;
  EXPECT_NE(a.output.find("target    trajectory error <= 5.00 cm"), std::string::npos) << a.output;
  const Outcome j = run("advise " + scene.string() + " --max-error 5cm --seconds 1 --methods 'a5:n=2|8:m=2:h=1/60' --repeat 1 --json");
  const json r = json::parse(j.output);
  EXPECT_EQ(r["reference"]["method"], "a1:h=1/480");
  EXPECT_GT(r["reference"]["seconds"].get<double>(), 0);
  EXPECT_DOUBLE_EQ(r["reference"]["dt"].get<double>(), 1.0 / 960);
  EXPECT_EQ(r["targets"][0]["metric"], "trajectory_error");
}

// Bad input is refused before the converged reference is computed (seconds of runs), naming the
// option; the reference's runs count against --budget, and a budget they use up is said, with how
// far they got, not answered with a search that ran after it.
TEST(Advise, InputCheckedFirstAndTheReferenceWithinTheBudget) {
  const fs::path d = folder();
  int links = 0;
  const fs::path scene = generatedChain(d, 5, &links);
  for (const char* methods : {"a9:n=2", "a5:n=2:m=oops"}) {
    const Outcome bad = run("advise " + scene.string() + " --max-error 5cm --methods '" + methods + "'");
    EXPECT_EQ(bad.status, 2) << bad.output;
    EXPECT_NE(bad.output.find(std::string("--methods: \"") + methods + "\": "), std::string::npos) << bad.output;
    EXPECT_EQ(bad.output.find("computing a converged one"), std::string::npos) << bad.output;
  }
  const Outcome out = run("advise " + scene.string() + " --max-error 5cm --seconds 1 --budget 10ms --methods 'a5:n=2:m=2:h=1/60'");
  EXPECT_EQ(out.status, 1) << out.output;
  EXPECT_NE(out.output.find("the time budget (0.01 s) ran out after "), std::string::npos) << out.output;
  EXPECT_NE(out.output.find(" s computing a converged reference for " + scene.string() + " over 1 s: the reference a1:h=1/480 was at step "),
            std::string::npos)
      << out.output;
  EXPECT_NE(out.output.find("Give a larger --budget"), std::string::npos) << out.output;
  EXPECT_EQ(out.output.find("searched  "), std::string::npos) << out.output;
}

// The margin is printed where it means something: under an at-most bound, above an at-least one
// (how far beyond it), and none for a yes-or-no check: the projectile that stays before the
// wall is not "100 % under" anything.
TEST(Advise, AMarginWhereABoundGivesOne) {
  const Outcome wall = run("advise assets/scenes/atlas/projectile_wall.json --methods a5 --repeat 1");
  ASSERT_EQ(wall.status, 0) << wall.output;
  EXPECT_NE(wall.output.find("ball stayed inside its box\n"), std::string::npos) << wall.output;
  EXPECT_EQ(wall.output.find(" % "), std::string::npos) << wall.output;
  const Outcome wallJson = run("advise assets/scenes/atlas/projectile_wall.json --methods a5 --repeat 1 --json");
  ASSERT_EQ(wallJson.status, 0) << wallJson.output;
  EXPECT_TRUE(json::parse(wallJson.output)["best"]["margin"].is_null()) << wallJson.output;
  // The implicit gyroscopic term lets the handle flip: turned 180 deg against at least 143 deg.
  const std::string flip = "advise assets/scenes/atlas/dzhanibekov_implicit.json --methods 'a2:m=2:h=1/30' --repeat 1";
  const Outcome text = run(flip);
  ASSERT_EQ(text.status, 0) << text.output;
  EXPECT_NE(text.output.find(" % above its bound)"), std::string::npos) << text.output;
  const Outcome j = run(flip + " --json");
  ASSERT_EQ(j.status, 0) << j.output;
  const json best = json::parse(j.output)["best"];
  const double share = best["value"].get<double>();  // bound / turned, the check's ratio
  ASSERT_GT(share, 0);
  EXPECT_NEAR(best["margin"].get<double>(), 1 / share - 1, 1e-12);  // (turned - bound) / bound
  EXPECT_GT(best["margin"].get<double>(), 0);
  EXPECT_NE(best["margin_text"].get<std::string>().find("% above its bound"), std::string::npos);
}

// The atlas on two scenes and three methods: the page with every cell filled, a clip per group of
// four, the records, the charts, and the verdict table written on request.
TEST(Atlas, PageClipsAndTables) {
  const fs::path d = folder();
  const Outcome a = run("atlas -o " + d.string() + " --scenes projectile_wall,friction_ramp --methods a2:m=4,a5,bullet:it=10 "
                        "--clip-seconds 0.5 --fps 10 --size 320x180 --write-expected " + (d / "expected.json").string() +
                        " --expected tests/data/atlas_expected.json");
  ASSERT_EQ(a.status, 0) << a.output;
  std::ifstream page(d / "index.html");
  std::stringstream html;
  html << page.rdbuf();
  const std::string h = html.str();
  size_t cells = 0;
  for (size_t at = h.find("<td class=\""); at != std::string::npos; at = h.find("<td class=\"", at + 1))
    cells += h.compare(at + 11, 4, "pass") == 0 || h.compare(at + 11, 4, "fail") == 0;
  EXPECT_EQ(cells, 6u);  // 2 scenes x 3 methods
  EXPECT_NE(h.find("ball left its box (passed through)"), std::string::npos);  // Bullet tunnels
  EXPECT_NE(h.find("clips/projectile_wall-1.mp4"), std::string::npos);
  EXPECT_NE(h.find("charts/friction_ramp-pareto.png"), std::string::npos);
  EXPECT_NE(h.find("Every verdict agrees with the expected table"), std::string::npos) << h;
  EXPECT_GT(fs::file_size(d / "clips" / "projectile_wall-1.mp4"), 1000u);
  EXPECT_EQ(rows(d / "atlas.jsonl").size(), 6u);
  std::ifstream doc(d / "atlas.json");
  const json j = json::parse(doc);
  EXPECT_EQ(j["verdicts"]["projectile_wall"]["bullet:it=10"], "fail");
  std::ifstream exp(d / "expected.json");
  EXPECT_EQ(json::parse(exp)["verdicts"], j["verdicts"]);
  std::ifstream md(d / "atlas.md");
  std::stringstream mdText;
  mdText << md.rdbuf();
  EXPECT_NE(mdText.str().find("| projectile_wall |"), std::string::npos);
}

// A bare name is the atlas's scene: pyramid_40 names assets/scenes/atlas/pyramid_40.json, not the
// scene of assets/scenes by that name (which states no criteria and was refused).
TEST(Atlas, ABareNameIsTheAtlasScene) {
  const fs::path d = folder();
  const Outcome a = run("atlas -q --no-clips -o " + d.string() + " --scenes pyramid_40 --methods a2:m=2");
  ASSERT_EQ(a.status, 0) << a.output;
  const std::vector<json> r = rows(d / "atlas.jsonl");
  ASSERT_EQ(r.size(), 1u);
  EXPECT_NE(r[0]["scene_file"].get<std::string>().find("atlas/pyramid_40.json"), std::string::npos) << r[0].dump();
}

TEST(LabCommands, EveryCommandHasHelp) {
  for (const std::string c : {"sweep", "sweep merge", "chart", "atlas", "advise"}) {
    const Outcome r = run(c + " --help");
    EXPECT_EQ(r.status, 0) << c;
    EXPECT_NE(r.output.find("Usage"), std::string::npos) << r.output;
  }
  const Outcome s = run("scenes");
  EXPECT_NE(s.output.find("atlas/card_house"), std::string::npos) << s.output;
  EXPECT_NE(s.output.find("reference/pendulum_5deg"), std::string::npos) << s.output;
}

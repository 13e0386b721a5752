// `substep snapshot`: golden images of a user's scenes. Exit status 0 for a match, 1 for a
// moved body or another size, 2 for a missing golden and other bad input, 3 for divergence;
// --update; a diff image that marks the moved body and nothing else; renders identical across
// processes; --compare of two files. Runs the binary.
#include "physics/scene_file.h"
#include "render/gl_renderer.h"
#include "render/image.h"
#include "render/session.h"
#include "run_substep.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace substep;
using namespace substep::render;
using substep_test::Outcome;

namespace {

Outcome run(const std::string& args, const std::string& env = "") { return substep_test::runSubstep("snapshot " + args, env); }

using substep_test::listing;

// A folder per test (CTest runs tests in parallel), emptied first.
fs::path scratch() { return substep_test::emptyScratchFolder("test_snapshot_cli_out"); }

// Two boxes on the ground, seen from a fixed camera; `x` places the right one.
std::string twoBoxes(double x) {
  return R"({"bodies": [
    {"name": "ground", "static": true, "shape": {"type": "box", "half_extents": [10, 0.5, 10]}, "position": [0, -0.5, 0]},
    {"name": "left", "shape": {"type": "box", "half_extents": [0.5, 0.5, 0.5]}, "position": [-1.5, 0.5, 0], "mass": 1},
    {"name": "right", "shape": {"type": "box", "half_extents": [0.5, 0.5, 0.5]}, "position": [)" +
         std::to_string(x) + R"(, 0.5, 0], "mass": 1}],
  "cameras": [{"name": "default", "target": [0, 0.5, 0], "yaw": 20, "pitch": 20, "distance": 8}]})";
}

fs::path writeScene(const fs::path& file, const std::string& json) {
  fs::create_directories(file.parent_path());
  std::ofstream(file) << json;
  return file;
}

}  // namespace

TEST(SnapshotCli, HelpListsTheOptions) {
  const Outcome r = run("--help");
  EXPECT_EQ(r.status, 0);
  for (const char* o : {"--at", "--golden", "--update", "--threshold", "--max-share", "--out", "--compare", "--diff",
                        "--step-cost", "--panels", "--size", "--camera", "-q", "Exit status", "docs/snapshots.md"})
    EXPECT_NE(r.output.find(o), std::string::npos) << o;
}

// --update writes the goldens; the same command without it matches; another --update with
// nothing changed leaves them alone.
TEST(SnapshotCli, UpdateThenTheSameCommandMatches) {
  const fs::path d = scratch(), g = d / "goldens";
  const std::string args = "assets/scenes/stack.json --at 1.0,0.5 --size 160x90 --golden " + g.string();
  Outcome r = run(args + " --update");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("created   " + (g / "stack@0.5.png").string()), std::string::npos) << r.output;
  EXPECT_EQ(listing(g), (std::vector<std::string>{"stack@0.5.png", "stack@1.0.png"}));
  EXPECT_EQ(readPng((g / "stack@1.0.png").string()).width, 160);
  r = run(args);
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("match     stack@0.5: 0 pixels differ"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("match     stack@1.0: 0 pixels differ"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("all 2 frames match"), std::string::npos) << r.output;
  r = run(args + " --update");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("unchanged " + (g / "stack@1.0.png").string()), std::string::npos) << r.output;
  r = run(args + " -q");  // nothing but mismatches and errors (LeakSanitizer may add its summary)
  EXPECT_EQ(r.status, 0) << r.output;
  for (const char* said : {"scene", "solver", "match", "stack@"})
    EXPECT_EQ(r.output.find(said), std::string::npos) << said << " in\n" << r.output;
  EXPECT_EQ(listing(g), (std::vector<std::string>{"stack@0.5.png", "stack@1.0.png"}));
}

// A body moved: exit 1, the actual frame and a diff next to the golden, and the diff's red pixels
// are the moved box's, at its old place and its new one, and nowhere else.
TEST(SnapshotCli, AMovedBodyIsAMismatchAndTheDiffMarksItAlone) {
  const fs::path d = scratch(), g = d / "goldens";
  // Same file name in two folders: one golden name, two scenes.
  const fs::path before = writeScene(d / "before" / "boxes.json", twoBoxes(1.5));
  const fs::path after = writeScene(d / "after" / "boxes.json", twoBoxes(1.9));
  const std::string common = " --at 0 --size 320x180 --shadow-size 0 --golden " + g.string();
  ASSERT_EQ(run(before.string() + common + " --update").status, 0);
  const Outcome r = run(after.string() + common);
  ASSERT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("MISMATCH  boxes@0.0: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("largest channel difference"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--update"), std::string::npos) << r.output;
  EXPECT_EQ(listing(g), (std::vector<std::string>{"boxes@0.0.actual.png", "boxes@0.0.diff.png", "boxes@0.0.png"}));
  const Image diff = readPng((g / "boxes@0.0.diff.png").string());

  // Where the right box covers anything, before and after: the frame drawn with it against the
  // frame drawn without it (no shadows, a fixed camera: nothing else depends on it).
  GlRenderer renderer(320, 180, RendererOptions{AntiAliasing::Fxaa, 1, 0, ""});
  auto footprint = [&](const fs::path& file) {
    auto scene = std::make_shared<const Scene>(loadScene(file.string()));
    Look look;
    look.camera = chooseCamera(*scene, {});
    const RenderSession s(scene, {{resolve(scene->solver), ""}}, look);
    std::vector<DrawList> lists = s.drawLists();
    const Image with = renderer.render(lists[0]);
    auto& solids = lists[0].solids;
    solids.erase(std::remove_if(solids.begin(), solids.end(), [](const Instance& in) { return in.body == 2; }),
                 solids.end());
    const Image without = renderer.render(lists[0]);
    // The golden is what `substep snapshot` drew of `before`: the same session and renderer here.
    if (file == before) {
      EXPECT_EQ(with.rgba, readPng((g / "boxes@0.0.png").string()).rgba);
    }
    return compareImages(without, with, CompareOptions{0, 1.0}).diff;
  };
  const Image old = footprint(before), now = footprint(after);
  auto red = [](const Image& img, int x, int y) {
    const uint8_t* p = img.pixel(x, y);
    return p[0] == 255 && p[1] == 0 && p[2] == 0;
  };
  long long marked = 0, outside = 0, oldOnly = 0, newOnly = 0, covered = 0;
  for (int y = 0; y < 180; ++y)
    for (int x = 0; x < 320; ++x) {
      const bool o = red(old, x, y), n = red(now, x, y);
      covered += o || n;
      if (!red(diff, x, y)) continue;
      ++marked;
      outside += !o && !n;
      oldOnly += o && !n;
      newOnly += n && !o;
    }
  EXPECT_EQ(outside, 0) << marked << " marked pixels";
  EXPECT_GT(oldOnly, 100);  // where it was
  EXPECT_GT(newOnly, 100);  // where it is
  EXPECT_GT(marked, covered / 3) << covered;
}

// --out takes the actual and diff images; a later match removes what a mismatch left.
TEST(SnapshotCli, OutFolderAndStaleImages) {
  const fs::path d = scratch(), g = d / "goldens", out = d / "out";
  const fs::path before = writeScene(d / "before" / "boxes.json", twoBoxes(1.5));
  const fs::path after = writeScene(d / "after" / "boxes.json", twoBoxes(1.9));
  const std::string common = " --at 0 --size 160x90 --golden " + g.string() + " --out " + out.string();
  ASSERT_EQ(run(before.string() + common + " --update").status, 0);
  ASSERT_EQ(run(after.string() + common).status, 1);
  EXPECT_EQ(listing(g), std::vector<std::string>{"boxes@0.0.png"});
  EXPECT_EQ(listing(out), (std::vector<std::string>{"boxes@0.0.actual.png", "boxes@0.0.diff.png"}));
  const Outcome r = run(before.string() + common);
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(listing(out).empty()) << listing(out).front();
}

// A golden of another size: a mismatch that says both sizes, with the actual image and no diff.
TEST(SnapshotCli, AnotherSizeIsAMismatch) {
  const fs::path d = scratch(), g = d / "goldens";
  ASSERT_EQ(run("assets/scenes/stack.json --at 0 --size 160x90 --golden " + g.string() + " --update").status, 0);
  const Outcome r = run("assets/scenes/stack.json --at 0 --size 320x180 --golden " + g.string());
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("sizes differ: expected 160x90, actual 320x180"), std::string::npos) << r.output;
  EXPECT_EQ(listing(g), (std::vector<std::string>{"stack@0.0.actual.png", "stack@0.0.png"}));
}

// Bad input: exit 2 and a message naming what is wrong; a missing golden says how to make it.
TEST(SnapshotCli, BadInputExitsWithStatus2) {
  const fs::path d = scratch(), g = d / "goldens";
  { std::ofstream(d / "text.png") << "not a png"; }
  fs::create_directories(g);
  { std::ofstream(g / "stack@0.5.png") << "not a png"; }
  const std::string scene = "assets/scenes/stack.json ";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {scene + "--at 1 --golden " + g.string(), "stack@1.0.png: no golden image; to create it, run the same command with --update"},
      {scene + "--at 0.5 --golden " + g.string(), "stack@0.5.png: not a readable PNG"},
      {"--at 1 --golden " + g.string(), "expected a scene file"},
      {scene + "--golden " + g.string(), "--at: give the simulated times"},
      {scene + "--at 1", "--golden: give the folder"},
      {scene + "--at -1 --golden " + g.string(), "--at"},
      {scene + "--at 1 --golden " + g.string() + " --threshold 300", "--threshold"},
      {scene + "--at 1 --golden " + g.string() + " --max-share 2", "--max-share"},
      {scene + "--at 1 --golden " + g.string() + " --size 8x8", "--size 8x8"},
      {scene + "--at 1 --golden " + g.string() + " --kappa 0.5", "--kappa: a2 does not use it (a3, a4, a5 do)"},
      {scene + "--at 1 --golden " + g.string() + " --panels a9,a2", "unknown algorithm \"a9\""},
      {scene + "--at 1 --golden " + g.string() + " --diff x.png", "--diff: only with --compare"},
      {scene + "--at 1 --golden /proc/forbidden --update", "/proc/forbidden"},
      {"assets/scenes/no_such.json --at 1 --golden " + g.string() + " --update", "cannot open"},
      {"--compare " + (d / "text.png").string() + " " + (d / "text.png").string(), "not a readable PNG"},
      {"--compare " + (d / "none.png").string() + " " + (d / "text.png").string(), "none.png: cannot open"},
      {scene + "--compare a.png b.png", "leave out the scene"},
      {"--compare a.png", "--compare"},
  };
  for (const auto& [args, fragment] : cases) {
    const Outcome r = run(args);
    EXPECT_EQ(r.status, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(fragment), std::string::npos) << args << "\n" << r.output;
  }
  EXPECT_EQ(listing(g), std::vector<std::string>{"stack@0.5.png"});
}

// The frames are the same in every process, whatever llvmpipe's thread count: zero differing
// pixels between two runs (the HUD has no wall-clock text unless --step-cost).
TEST(SnapshotCli, FramesAreIdenticalAcrossProcesses) {
  const fs::path d = scratch();
  const std::string args =
      "assets/scenes/ragdoll.json --at 0.5,1.0 --panels a2:m=4,a5:n=4 --color error --joints --contacts --size 320x180 --update";
  ASSERT_EQ(run(args + " --golden " + (d / "one").string(), "LP_NUM_THREADS=1").status, 0);
  ASSERT_EQ(run(args + " --golden " + (d / "two").string(), "LP_NUM_THREADS=4").status, 0);
  for (const char* name : {"ragdoll@0.5.png", "ragdoll@1.0.png"}) {
    const CompareResult r = compareImages(readPng((d / "one" / name).string()), readPng((d / "two" / name).string()),
                                          CompareOptions{0, 0.0});
    EXPECT_TRUE(r.sameSize) << name;
    EXPECT_EQ(r.differing, 0) << name << ": " << r.summary();
    EXPECT_EQ(r.maxDelta, 0) << name;
  }
  // Asked for, the measured step cost is drawn: the frame is no longer the golden.
  const Outcome r = run("assets/scenes/ragdoll.json --at 0.5 --panels a2:m=4,a5:n=4 --color error --joints --contacts "
                        "--size 320x180 --step-cost --golden " + (d / "one").string());
  EXPECT_EQ(r.status, 1) << r.output;
}

// A diverging scene: exit 3 and no golden written.
TEST(SnapshotCli, DivergenceStopsWithStatus3AndWritesNothing) {
  const fs::path d = scratch(), g = d / "goldens";
  const Outcome r = run("tests/data/diverging.json --at 0.5,1 --size 160x90 --update --golden " + g.string());
  EXPECT_EQ(r.status, 3) << r.output;
  EXPECT_NE(r.output.find("diverged"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"light\""), std::string::npos) << r.output;
  EXPECT_TRUE(listing(g).empty()) << listing(g).front();
}

// --compare A B: the comparison alone, for images made elsewhere.
TEST(SnapshotCli, ComparesTwoFiles) {
  const fs::path d = scratch();
  Image a(64, 32, 0x404040ffu), b = a, small(32, 32, 0x404040ffu);
  for (int y = 10; y < 20; ++y)
    for (int x = 40; x < 50; ++x) b.pixel(x, y)[1] = 200;  // 100 pixels of 2048 changed
  writePng((d / "a.png").string(), a);
  writePng((d / "b.png").string(), b);
  writePng((d / "small.png").string(), small);
  const std::string A = (d / "a.png").string(), B = (d / "b.png").string();
  Outcome r = run("--compare " + A + " " + A);
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("match     0 pixels differ"), std::string::npos) << r.output;
  r = run("--compare " + A + " " + B + " --diff " + (d / "d.png").string());
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("100 pixels differ (4.8828%), largest channel difference 136"), std::string::npos) << r.output;
  const Image diff = readPng((d / "d.png").string());
  EXPECT_EQ(diff.pixel(45, 15)[0], 255);
  EXPECT_EQ(diff.pixel(45, 15)[1], 0);
  EXPECT_NE(diff.pixel(5, 5)[0], 255);
  // Tolerance from the command line: 5 % of the pixels may differ.
  EXPECT_EQ(run("--compare " + A + " " + B + " --max-share 0.05").status, 0);
  EXPECT_EQ(run("--compare " + A + " " + B + " --threshold 136").status, 0);
  r = run("--compare " + A + " " + (d / "small.png").string() + " --diff " + (d / "d2.png").string());
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("sizes differ: expected 64x32, actual 32x32"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("no diff image"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(d / "d2.png"));
}

// `substep render`: outputs (PNG, PNG sequence, MP4), comparisons, progress, bad input (exit 2),
// divergence (exit 3), a failing ffmpeg (exit 1), and nothing partial left behind. Runs the binary.
#include "app/common.h"
#include "render/image.h"
#include "run_substep.h"

#include <gtest/gtest.h>

#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <thread>
#include <vector>

namespace fs = std::filesystem;

namespace {

using substep_test::Outcome;

Outcome run(const std::string& args, const std::string& env = "") { return substep_test::runSubstep(args, env); }

using substep_test::listing;

// A folder per test (CTest runs tests in parallel), emptied first.
fs::path scratch() { return substep_test::emptyScratchFolder("test_render_cli_out"); }

std::string probe(const fs::path& f) {
  const std::string cmd = "ffprobe -v error -count_frames -select_streams v:0 -show_entries "
                          "stream=codec_name,width,height,pix_fmt,nb_read_frames -of csv=p=0 " + f.string() + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  char buf[512] = {0};
  const size_t n = fread(buf, 1, sizeof buf - 1, p);
  pclose(p);
  return std::string(buf, n);
}

bool haveFfmpeg() { return std::system("command -v ffmpeg >/dev/null 2>&1 && command -v ffprobe >/dev/null 2>&1") == 0; }

}  // namespace

TEST(RenderCli, HelpListsTheOptions) {
  const Outcome r = run("render --help");
  EXPECT_EQ(r.status, 0);
  for (const char* o : {"--compare", "--fps", "--size", "--at", "--seconds", "--camera", "--color", "--contacts", "--joints",
                        "--forces", "--joint-errors", "--force-scale", "--algo", "a2:m=4,a5:n=4", "--aa", "--samples",
                        "--shadow-size"})
    EXPECT_NE(r.output.find(o), std::string::npos) << o;
}

// Every kind of bad argument: exit status 2, a message naming the problem, and no output file.
TEST(RenderCli, BadArgumentsExitWithStatus2AndWriteNothing) {
  const fs::path d = scratch();
  const std::string png = (d / "x.png").string(), mp4 = (d / "x.mp4").string();
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"assets/scenes/stack.json --size 0x0 -o " + png, "--size 0x0"},
      {"assets/scenes/stack.json --size 7681x4320 -o " + png, "at most 7680x4320"},
      {"assets/scenes/stack.json --size 1280x4321 -o " + png, "4320"},
      {"assets/scenes/stack.json --size big -o " + png, "WIDTHxHEIGHT"},
      {"assets/scenes/stack.json --fps 0 -o " + mp4, "--fps"},
      {"assets/scenes/stack.json --fps 241 -o " + mp4, "--fps"},
      {"assets/scenes/stack.json --algo a9 -o " + png, "--algo"},
      {"assets/scenes/stack.json --compare a9,a2 -o " + png, "unknown algorithm \"a9\""},
      {"assets/scenes/stack.json --compare a2 -o " + png, "2 to 4 panels"},
      {"assets/scenes/stack.json --compare a2:kappa=1,a1 -o " + png, "kappa: a2 does not use it"},
      {"assets/scenes/stack.json --compare a1,a2 --algo a2 -o " + png, "excludes"},
      {"assets/scenes/stack.json -o /proc/forbidden/x.png", "/proc/forbidden"},
      {"assets/scenes/stack.json -o " + (d / "x.gif").string(), "cannot tell what to write"},
      {"assets/scenes/stack.json --seconds 2 -o " + png, "--at"},
      {"assets/scenes/stack.json --at 2 -o " + mp4, "--at: only for a single .png"},
      {"assets/scenes/stack.json --size 321x180 -o " + mp4, "even width and height"},
      {"assets/scenes/stack.json --camera nope -o " + png, "has no camera \"nope\" (it has: default, side)"},
      {"assets/scenes/stack.json --follow ghost -o " + png, "no body \"ghost\""},
      {"assets/scenes/stack.json --highlight ghost -o " + png, "no body \"ghost\""},
      {"assets/scenes/stack.json --color rainbow -o " + png, "--color"},
      {"assets/scenes/stack.json --aa smaa -o " + png, "--aa"},
      {"assets/scenes/stack.json --samples 3 -o " + png, "--samples"},
      {"assets/scenes/no_such.json -o " + png, "cannot open"},
      {"tests/data/bad/negative_mass.json -o " + png, "bodies[0].mass"},
      // Non-finite and absurd numbers: NaN passes a range check, and a NaN camera draws a blank frame.
      {"assets/scenes/stack.json --yaw nan -o " + png, "--yaw: expected a number"},
      {"assets/scenes/stack.json --yaw inf -o " + png, "--yaw: expected a number"},
      {"assets/scenes/stack.json --target nan,nan,nan -o " + png, "--target: expected a number"},
      {"assets/scenes/stack.json --target 1e308,0,0 -o " + png, "--target: expected a number in [-100000, 100000]"},
      {"assets/scenes/stack.json --orbit nan -o " + png, "--orbit: expected a number"},
      {"assets/scenes/stack.json --distance nan -o " + png, "--distance"},
      {"assets/scenes/stack.json --pitch nan -o " + png, "--pitch"},
      {"assets/scenes/stack.json --speed-scale inf -o " + png, "--speed-scale"},
      {"assets/scenes/stack.json --forces --force-scale -1 -o " + png, "--force-scale"},
      {"assets/scenes/stack.json --forces --force-scale nan -o " + png, "--force-scale"},
      {"assets/scenes/stack.json --kappa nan --algo a5 -o " + png, "--kappa"},
      {"assets/scenes/stack.json --compare '' -o " + png, "--compare: expected 2 to 4 settings"},
      {"assets/scenes/stack.json --preset '' --algo a5 -o " + png, "--preset"},
      // A video into a folder that only looks writable fails before any frame, as a PNG does.
      {"assets/scenes/stack.json --seconds 0.1 -o /proc/x.mp4", "-o /proc/x.mp4: cannot create a file in /proc"},
      {"assets/scenes/stack.json -o /proc/x.png", "/proc"},
  };
  for (const auto& [args, fragment] : cases) {
    const Outcome r = run("render " + args);
    EXPECT_EQ(r.status, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(fragment), std::string::npos) << args << "\n" << r.output;
  }
  EXPECT_TRUE(listing(d).empty()) << listing(d).front();
  // ffmpeg missing: a clear message, exit status 2, before any work.
  const Outcome r = run("render assets/scenes/stack.json --seconds 0.1 -o " + mp4, "PATH=/nonexistent");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("needs the ffmpeg program"), std::string::npos) << r.output;
  EXPECT_TRUE(listing(d).empty());
}

// The acceptance's single frame: a PNG of the stack at t = 1 s, with the HUD.
TEST(RenderCli, WritesOnePngAtATime) {
  const fs::path d = scratch(), f = d / "s.png";
  const Outcome r = run("render assets/scenes/stack.json --at 1.0 --size 320x180 -o " + f.string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("wrote"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("60 steps"), std::string::npos) << r.output;  // 1 s at h = 1/60
  const substep::render::Image img = substep::render::readPng(f.string());
  EXPECT_EQ(img.width, 320);
  EXPECT_EQ(img.height, 180);
  // Not a flat image: count distinct colours.
  std::set<uint32_t> colours;
  for (size_t i = 0; i < img.rgba.size(); i += 4)
    colours.insert(img.rgba[i] << 16 | img.rgba[i + 1] << 8 | img.rgba[i + 2]);
  EXPECT_GT(colours.size(), 500u);
  EXPECT_EQ(listing(d), std::vector<std::string>{"s.png"});
  EXPECT_NE(r.output.find("FXAA"), std::string::npos) << r.output;  // the default anti-aliasing, named
}

// --forces draws the impulses, --force-scale makes the arrows longer: each changes the frame.
TEST(RenderCli, ForceArrowsFollowTheirOptions) {
  const fs::path d = scratch();
  auto frame = [&](const std::string& name, const std::string& options) {
    const fs::path f = d / name;
    const Outcome r = run("render assets/scenes/stack.json --at 1.0 --size 320x180 --no-hud " + options + " -o " +
                          f.string());
    EXPECT_EQ(r.status, 0) << r.output;
    return substep::render::readPng(f.string());
  };
  auto differing = [](const substep::render::Image& a, const substep::render::Image& b) {
    long long n = 0;
    for (size_t i = 0; i < a.rgba.size(); i += 4)
      n += std::abs(int(a.rgba[i]) - int(b.rgba[i])) + std::abs(int(a.rgba[i + 1]) - int(b.rgba[i + 1])) > 48;
    return n;
  };
  const substep::render::Image plain = frame("plain.png", ""), forces = frame("forces.png", "--forces"),
                               longer = frame("longer.png", "--forces --force-scale 20");
  EXPECT_GT(differing(plain, forces), 50);
  EXPECT_GT(differing(plain, longer), 2 * differing(plain, forces));  // the automatic scale is 5 m per N s
}

// Anti-aliasing: FXAA by default, multisampling with --samples (alone, unless --aa fxaa), none.
TEST(RenderCli, AntiAliasingIsSelectable) {
  const fs::path d = scratch();
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"", "FXAA"}, {"--samples 4", "4x MSAA\n"}, {"--samples 4 --aa fxaa", "4x MSAA + FXAA"}, {"--aa none", "no anti-aliasing"}};
  for (const auto& [args, info] : cases) {
    const fs::path f = d / "a.png";
    const Outcome r = run("render assets/scenes/stack.json --at 0.5 --size 160x90 " + args + " -o " + f.string());
    ASSERT_EQ(r.status, 0) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(info), std::string::npos) << args << "\n" << r.output;
    EXPECT_EQ(substep::render::readPng(f.string()).width, 160);
  }
}

TEST(RenderCli, WritesAnH264VideoAtTheVideoRate) {
  if (!haveFfmpeg()) GTEST_SKIP() << "ffmpeg is not installed";
  const fs::path d = scratch(), f = d / "v.mp4";
  // Physics at 1/60 s, frames at 1/30 s: 0.5 s is 15 frames.
  const Outcome r = run("render assets/scenes/stack.json --seconds 0.5 --fps 30 --size 320x180 -o " + f.string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(probe(f), "h264,320,180,yuv420p,15\n");
  EXPECT_EQ(listing(d), std::vector<std::string>{"v.mp4"});
}

TEST(RenderCli, WritesANumberedPngSequenceIntoAFolder) {
  const fs::path d = scratch(), out = d / "frames";
  fs::create_directories(out);
  { std::ofstream stale(out / "frame_00009.png"); }  // from an earlier, longer render
  { std::ofstream mine(out / "notes.txt"); }          // not ours: left alone
  const Outcome r = run("render assets/scenes/pendulum_chain.json --seconds 0.2 --fps 20 --size 160x90 -o " +
                        out.string() + "/");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(listing(out), (std::vector<std::string>{"frame_00000.png", "frame_00001.png", "frame_00002.png",
                                                      "frame_00003.png", "notes.txt"}));
  EXPECT_EQ(listing(d), std::vector<std::string>{"frames"});  // no staging folder left
  // Frames differ: the chain swings.
  EXPECT_NE(substep::render::readPng((out / "frame_00000.png").string()).rgba,
            substep::render::readPng((out / "frame_00003.png").string()).rgba);
}

// --compare draws the panels side by side, each labelled with its setting.
TEST(RenderCli, ComparesSettingsInAGrid) {
  const fs::path d = scratch(), f = d / "c.png";
  const Outcome r = run("render assets/scenes/pendulum_chain.json --compare a1,a2:m=2:omega=1.2 --at 0.5 --size 320x180 -o " +
                        f.string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("solver    a1"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("m=2 ω=1.2"), std::string::npos) << r.output;
  const substep::render::Image img = substep::render::readPng(f.string());
  // The border between the panels is a dark column at the middle.
  const uint8_t* border = img.pixel(159, 120);
  EXPECT_LT(border[0] + border[1] + border[2], 30);
}

// The bar is for a person at a terminal: drawn when stderr is one (here a pseudo-terminal made
// by script(1)), not into a pipe or a log, and never with -q.
TEST(RenderCli, ShowsProgressForLongRendersOnATerminal) {
  const fs::path d = scratch();
  // runSubstepOnTerminal draws the bar from the start ($SUBSTEP_PROGRESS_DELAY=0): 30 frames will do.
  const std::string args = "render assets/scenes/pyramid.json --seconds 0.5 --size 160x90 -o " + (d / "p").string();
  Outcome r = substep_test::runSubstepOnTerminal(args);
  EXPECT_NE(r.output.find("render ["), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("/30"), std::string::npos) << r.output;  // frames done of all
  EXPECT_NE(r.output.find("left"), std::string::npos) << r.output;  // time left
  r = substep_test::runSubstepOnTerminal(args + " -q");
  EXPECT_EQ(r.output.find("render ["), std::string::npos) << r.output;
  r = run(args);  // a pipe
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output.find("render ["), std::string::npos) << r.output;
}

// A simulation that diverges stops the render: exit status 3, a message naming the body, no file.
TEST(RenderCli, DivergenceStopsWithStatus3AndNoFile) {
  const fs::path d = scratch();
  for (const std::string out : {"x.png", "x.mp4", "frames"}) {
    const std::string args = out == "x.png" ? " --at 1" : " --seconds 1";
    const Outcome r = run("render tests/data/diverging.json --size 160x90" + args + " -o " + (d / out).string());
    EXPECT_EQ(r.status, 3) << out << "\n" << r.output;
    EXPECT_NE(r.output.find("diverged"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("\"light\""), std::string::npos) << r.output;
  }
  EXPECT_TRUE(listing(d).empty()) << listing(d).front();
}

// ffmpeg failing: a clear message, exit status 1, and the partial file removed.
// Ctrl-C during a render: exit status 130, "interrupted", no output and no temporary left.
TEST(RenderCli, InterruptLeavesNothingBehind) {
  const fs::path d = scratch();
  for (const std::string out : {"v.mp4", "frames"}) {
    const Outcome r = substep_test::runShell("(" SUBSTEP_EXE " render assets/scenes/pyramid.json --seconds 60 --size 320x180 -q -o " +
                                             (d / out).string() + " & pid=$!; sleep 2; kill -INT $pid; wait $pid)");
    EXPECT_EQ(r.status, 130) << out << "\n" << r.output;
    EXPECT_NE(r.output.find("interrupted; no output written"), std::string::npos) << r.output;
  }
  EXPECT_TRUE(listing(d).empty()) << listing(d).front();
}

TEST(RenderCli, FailingFfmpegLeavesNothingBehind) {
  const fs::path d = scratch(), f = d / "v.mp4";
  const Outcome r = run("render assets/scenes/stack.json --seconds 1 --size 160x90 -o " + f.string(),
                        "SUBSTEP_FFMPEG=/bin/false");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("ffmpeg"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("status 1"), std::string::npos) << r.output;
  EXPECT_TRUE(listing(d).empty()) << listing(d).front();
}

// serve and render step on every core from kEveryCoreFromBodies moving bodies (below, handing the
// work out costs more than it saves: docs/benchmarks.md, "Threads"); static bodies do not count,
// and a scene's or the command line's threads win.
TEST(EveryCore, FromThreeThousandMovingBodiesUnlessTheSceneOrCommandLineSays) {
  using namespace substep;
  using app::kEveryCoreFromBodies;
  using app::onEveryCore;
  const SettingSpec& threads = settingOf(&SolverSettings::threads);
  const auto scene = [](long moving) {
    Scene s;
    s.model.bodies.resize(static_cast<size_t>(moving) + 1);
    s.model.bodies[0].isStatic = true;
    return s;
  };
  const double cores = std::min<double>(std::max(1u, std::thread::hardware_concurrency()), limits::kMaxThreads);
  EXPECT_FALSE(onEveryCore(scene(kEveryCoreFromBodies - 1), {}).has(threads));
  EXPECT_EQ(onEveryCore(scene(kEveryCoreFromBodies), {}).value(threads), cores);
  SolverOverrides given;
  given.set(&SolverSettings::threads, 1);
  EXPECT_EQ(onEveryCore(scene(kEveryCoreFromBodies), given).value(threads), 1.0);
  Scene fromFile = scene(kEveryCoreFromBodies);
  fromFile.solver.set(&SolverSettings::threads, 1);
  EXPECT_FALSE(onEveryCore(fromFile, {}).has(threads));  // the scene's own setting stands
}

// substep snapshot: snapshot image tests of a user's own scenes. Renders frames with the session
// `substep render` uses and compares each with a golden PNG, as image-diff tools in CI do (a
// threshold per channel, a share of pixels allowed to differ, a diff image, an update mode); or
// compares two PNG files made elsewhere. See docs/snapshots.md.
#include "app/commands.h"
#include "app/common.h"
#include "app/render_options.h"
#include "render/image.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>

namespace substep::app {

namespace {

namespace fs = std::filesystem;
using namespace substep::render;

struct SnapshotOptions {
  RenderOptions draw;
  std::vector<double> at;
  std::string golden, out, diff;
  std::vector<std::string> images;  // --compare A.png B.png
  CompareOptions tolerance;
  bool update = false, stepCost = false;
};

// The time in a golden's name: 1.0, 0.25, 2.125 (the shortest of up to six decimals, at least one).
std::string timeText(double t) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.6f", t);
  std::string s = buf;
  while (s.size() >= 2 && s.back() == '0' && s[s.size() - 2] != '.') s.pop_back();
  return s;
}

Image readImage(const std::string& path, const std::string& what) {
  try {
    return readPng(path);
  } catch (const std::runtime_error& e) {
    throw UsageError(what + e.what());
  }
}

std::string tolerance(const CompareOptions& t) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "allowed: %g%% of pixels over %d levels", 100 * t.maxShare, t.threshold);
  return buf;
}

// Removes what an earlier mismatch left, so what is there speaks of this run.
void removeStale(const fs::path& out, const std::string& name) {
  std::error_code ec;
  fs::remove(out / (name + ".actual.png"), ec);
  fs::remove(out / (name + ".diff.png"), ec);
}

int compareFiles(const SnapshotOptions& o) {
  const bool quiet = o.draw.quiet;
  if (!o.draw.scene.empty() || !o.at.empty() || !o.golden.empty() || o.update || !o.out.empty())
    throw UsageError("--compare A.png B.png compares two images alone; leave out the scene, --at, --golden, --update "
                     "and --out (or drop --compare to snapshot a scene)");
  if (!o.diff.empty()) checkWritable(o.diff, "--diff " + o.diff);
  const Image a = readImage(o.images[0], "--compare: "), b = readImage(o.images[1], "--compare: ");
  const CompareResult r = compareImages(a, b, o.tolerance);
  if (!r.match || !quiet)
    std::cout << (r.match ? "match     " : "MISMATCH  ") << r.summary() << " (" << tolerance(o.tolerance) << ")\n";
  if (!o.diff.empty()) {
    if (r.sameSize) {
      writePng(o.diff, r.diff);
      if (!quiet) std::cout << "diff      " << o.diff << " (differing pixels red over the first image, dimmed)\n";
    } else {
      std::cout << "no diff image: the sizes differ\n";
    }
  }
  return r.match ? 0 : kExitFailure;
}

// --- a scene's frames against its goldens -----------------------------------------------------

void checkSceneOptions(const SnapshotOptions& o) {
  if (!o.diff.empty())
    throw UsageError("--diff: only with --compare A.png B.png; a scene's mismatches write NAME.diff.png themselves");
  if (o.draw.scene.empty())
    throw UsageError("expected a scene file (substep snapshot SCENE --at T --golden DIR) or --compare A.png B.png");
  if (isRecordingPath(o.draw.scene))
    throw UsageError(o.draw.scene + ": snapshot tests step scene files; draw a recording with substep render " +
                     o.draw.scene + " -o frame.png --at T");
  if (o.at.empty()) throw UsageError("--at: give the simulated times of the frames to check, e.g. --at 0.5,1.0");
  if (o.golden.empty()) throw UsageError("--golden: give the folder of the golden images, e.g. --golden tests/goldens");
}

struct GoldenFrame {
  double t;
  std::string name;
  fs::path golden;
  Image expected, actual;
};

// In time order, each once, named from the scene file's name and the time.
std::vector<GoldenFrame> plannedFrames(const SnapshotOptions& o) {
  std::vector<double> times = o.at;
  std::sort(times.begin(), times.end());
  std::vector<GoldenFrame> frames;
  const std::string stem = fs::path(o.draw.scene).stem().string();
  for (double t : times) {
    const std::string name = stem + "@" + timeText(t);
    if (!frames.empty() && frames.back().name == name) continue;
    frames.push_back({t, name, fs::path(o.golden) / (name + ".png"), {}, {}});
  }
  return frames;
}

// The goldens read (or, to update them, their folder checked), and the folder of mismatches checked.
void checkGoldens(std::vector<GoldenFrame>& frames, const SnapshotOptions& o, const fs::path& out) {
  std::error_code ec;
  if (o.update) {
    checkWritable((fs::path(o.golden) / "x.png").string(), "--golden " + o.golden);
  } else {
    for (GoldenFrame& f : frames) {
      if (!fs::exists(f.golden, ec))
        throw UsageError(f.golden.string() + ": no golden image; to create it, run the same command with --update, "
                                             "then look at the image before committing it");
      f.expected = readImage(f.golden.string(), "");
    }
  }
  if (!o.out.empty()) checkWritable((out / "x.png").string(), "--out " + o.out);
}

// 0, or the exit status of a diverged panel.
int renderFrames(RenderSession& session, std::vector<GoldenFrame>& frames, const RenderOptions& d, int width, int height) {
  InterruptGuard interrupts;
  const std::unique_ptr<GlRenderer> renderer = d.makeRenderer(width, height);
  for (GoldenFrame& f : frames) {
    advanceShowingSteps(session, f.t, d.quiet);
    if (const Panel* p = session.firstDiverged()) return reportDivergence("substep snapshot", *p);
    session.frame(*renderer, f.actual);
  }
  return 0;
}

void updateGolden(const GoldenFrame& f, const fs::path& out, bool quiet) {
  std::error_code ec;
  std::string status = "created", note;
  if (fs::exists(f.golden, ec)) {
    Image old;
    try {
      old = readPng(f.golden.string());
    } catch (const std::runtime_error&) {
    }  // unreadable: rewritten
    const CompareResult r = compareImages(old, f.actual, CompareOptions{0, 0.0});
    status = r.sameSize && r.differing == 0 ? "unchanged" : "rewritten";
    if (status == "rewritten") note = " (was: " + r.summary() + ")";
  }
  if (status != "unchanged") writePng(f.golden.string(), f.actual);
  removeStale(out, f.name);
  if (!quiet) std::cout << std::left << std::setw(10) << status << f.golden.string() << note << "\n";
}

// A mismatch: the actual frame and the diff written beside the golden (or under --out), and named.
void reportMismatch(const GoldenFrame& f, const CompareResult& r, const CompareOptions& tol, const fs::path& out) {
  const std::string actual = (out / (f.name + ".actual.png")).string(), diff = (out / (f.name + ".diff.png")).string();
  writePng(actual, f.actual);
  std::error_code ignored;
  if (r.sameSize)
    writePng(diff, r.diff);
  else
    fs::remove(diff, ignored);  // an older one would speak of another size
  std::cout << "MISMATCH  " << f.name << ": " << r.summary() << " (" << tolerance(tol) << ")\n"
            << "          golden " << f.golden.string() << "\n"
            << "          actual " << actual << "\n";
  if (r.sameSize) std::cout << "          diff   " << diff << " (differing pixels red over the golden, dimmed)\n";
}

int compareWithGoldens(const std::vector<GoldenFrame>& frames, const CompareOptions& tol, const fs::path& out, bool quiet) {
  int mismatches = 0;
  for (const GoldenFrame& f : frames) {
    const CompareResult r = compareImages(f.expected, f.actual, tol);
    if (r.match) {
      removeStale(out, f.name);
      if (!quiet) std::cout << "match     " << f.name << ": " << r.summary() << "\n";
      continue;
    }
    ++mismatches;
    reportMismatch(f, r, tol, out);
  }
  if (mismatches > 0)
    std::cout << mismatches << " of " << frames.size() << " frames differ from their goldens; if the change is intended, "
              << "run again with --update and look at the new goldens before committing them\n";
  else if (!quiet)
    std::cout << "all " << frames.size() << " frames match\n";
  return mismatches > 0 ? kExitFailure : 0;
}

int snapshot(const SnapshotOptions& o) {
  if (!o.images.empty()) return compareFiles(o);
  const RenderOptions& d = o.draw;
  checkSceneOptions(o);
  int width = 0, height = 0;
  parseFrameSize(d.size, width, height);
  d.colourMode();
  std::vector<GoldenFrame> frames = plannedFrames(o);
  RenderSession session = d.makeSession(std::make_shared<const Scene>(load(d.scene)), o.stepCost);
  const fs::path out = o.out.empty() ? fs::path(o.golden) : fs::path(o.out);
  checkGoldens(frames, o, out);
  d.printHeader(session);
  if (const int status = renderFrames(session, frames, d, width, height)) return status;
  if (!o.update) return compareWithGoldens(frames, o.tolerance, out, d.quiet);
  for (const GoldenFrame& f : frames) updateGolden(f, out, d.quiet);
  return 0;
}

}  // namespace

void addSnapshotCommand(CLI::App& app, std::function<int()>& action) {
  auto opt = std::make_shared<SnapshotOptions>();
  CLI::App* cmd = app.add_subcommand(
      "snapshot", "Snapshot image tests: render a scene at given times and compare each frame with a golden PNG");
  cmd->footer(
      "\nsubstep snapshot SCENE --at T[,T2,...] --golden DIR [render options]\n"
      "  compares each frame with DIR/<scene>@<t>.png (e.g. stack@1.0.png); a mismatch writes <name>.actual.png and\n"
      "  <name>.diff.png (differing pixels red) next to the golden, or under --out. --update writes the goldens.\n"
      "substep snapshot --compare A.png B.png [--diff D.png]\n"
      "  compares two images made elsewhere.\n"
      "Exit status: 0 all match, 1 a frame differs (or the sizes), 2 bad input (a missing golden: run with --update),\n"
      "3 the simulation diverged. Frames are deterministic: the HUD shows no wall-clock time unless --step-cost.\n"
      "Grids of settings: --panels a2:m=4,a5:n=4 (render's --compare). See docs/snapshots.md.");
  opt->draw.add(*cmd, "--panels", "480x270");
  cmd->add_option("--at", opt->at, "Simulated times of the frames [s], comma separated, e.g. 0.5,1.0")
      ->delimiter(',')
      ->check(CLI::Range(0.0, 1e5));
  cmd->add_option("--golden", opt->golden, "Folder of the golden images <scene>@<t>.png");
  cmd->add_flag("--update", opt->update, "Write (or rewrite) the goldens instead of comparing; look at them before committing");
  cmd->add_option("--out", opt->out, "Folder for <name>.actual.png and <name>.diff.png of mismatches (default: --golden)");
  cmd->add_option("--threshold", opt->tolerance.threshold,
                  "A pixel differs when a channel differs by more than this, 0-255 (default 24)")
      ->check(CLI::Range(0, 255));
  cmd->add_option("--max-share", opt->tolerance.maxShare,
                  "Share of pixels that may differ in a match, 0-1 (default 0.0002: 26 pixels of 480x270)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_flag("--step-cost", opt->stepCost,
                "Show the measured step cost in the HUD (wall-clock time: frames then differ from run to run)");
  cmd->add_option("--compare", opt->images, "Compare two PNG files: --compare A.png B.png (A is the expected one)")
      ->expected(2);
  cmd->add_option("--diff", opt->diff, "With --compare: write the diff image here");
  cmd->callback([opt, &action] {
    action = [opt]() -> int { return snapshot(*opt); };
  });
}

}  // namespace substep::app

// substep-render-bench --rates: the frame rates of the pipelines against the drawing alone, in
// one run, for the targets of docs/rendering.md ("Frames at the pipeline's pace"):
//
//   video  `substep render SCENE --seconds S -o F.mp4` end to end (its own "rate" line: physics,
//          drawing, anti-aliasing, conversion and x264) against the rate the same frames (the
//          same times, camera, HUD and size) are drawn alone here, render() after render() on
//          one renderer: target at least 0.9x.
//   stream a live session (the server's, render/live_session.h) playing the scene with one viewer
//          taking every frame: the JPEG encoder's time against the draw's (both from the session's
//          stats, each frame's own), target at most 0.15x; the frames delivered against
//          min(asked rate, 1000 / draw ms), target at least 0.9x.
//
// Each round measures every scene's three in turn, so that a change of the machine's load falls
// on all of them; the verdicts are on the medians over the rounds.
#include "app/bench/render_rates.h"

#include "app/bench/bench_stats.h"
#include "app/common.h"
#include "app/render_options.h"
#include "render/gl_renderer.h"
#include "render/live_session.h"
#include "render/session.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace substep::app {
namespace {

using namespace substep::render;
using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::string shellQuote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// The substep executable beside this one (build/app/bench/.. /substep), or --substep.
std::string substepProgram(const std::string& given) {
  if (!given.empty()) return given;
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  const std::filesystem::path sibling = self.parent_path().parent_path() / "substep";
  if (ec || !std::filesystem::exists(sibling))
    throw UsageError("--rates: cannot find the substep program beside this one (" + sibling.string() +
                     "); give it with --substep PATH");
  return sibling.string();
}

// The session `substep render SCENE` makes by default (its panel, camera, HUD with the step cost).
RenderSession videoSession(const std::shared_ptr<const Scene>& scene) {
  RenderOptions o;
  return o.makeSession(scene, true);
}

// The frames' draw lists of `seconds` at `fps`, made before any timing.
std::vector<DrawList> videoLists(const std::shared_ptr<const Scene>& scene, double seconds, int fps) {
  RenderSession session = videoSession(scene);
  const long long frames = std::llround(seconds * fps);
  std::vector<DrawList> lists;
  lists.reserve(static_cast<size_t>(frames));
  for (long long k = 0; k < frames; ++k) {
    session.advanceTo(static_cast<double>(k) / fps);
    if (const Panel* p = session.firstDiverged()) throw std::runtime_error(scene->file + ": " + p->problem());
    lists.push_back(session.drawList(0));
  }
  return lists;
}

// Frames a second the renderer draws the lists, one after the other, as GlRenderer::render (the
// drawing, the read-back, the anti-aliasing and the row flip; the first frame's shader
// compilation counted, as in the video's rate).
double drawAloneRate(const std::vector<DrawList>& lists, int width, int height) {
  RenderOptions o;
  const std::unique_ptr<GlRenderer> renderer = o.makeRenderer(width, height);
  Image img;
  const auto t0 = Clock::now();
  for (const DrawList& list : lists) renderer->render({View{&list, Viewport{0, 0, width, height}}}, img);
  return static_cast<double>(lists.size()) / secondsSince(t0);
}

// `substep render` of the scene to a temporary MP4; the rate its report states.
double videoRate(const std::string& substep, const Scene& scene, const RatesOptions& o, const std::string& folder) {
  const std::string out = folder + "/rates.mp4";
  const std::string cmd = shellQuote(substep) + " render " + shellQuote(scene.file) + " --seconds " +
                          std::to_string(o.seconds) + " --fps " + std::to_string(o.fps) + " --size " + o.size + " -o " +
                          shellQuote(out) + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) throw std::runtime_error("cannot run " + cmd);
  std::string text;
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof buf, p)) text.append(buf, n);
  const int status = pclose(p);
  const size_t at = text.find("\nrate ");
  long long frames = 0;
  double seconds = 0;
  if (status != 0 || at == std::string::npos ||
      std::sscanf(text.c_str() + at, "\nrate %lld frames in %lf s", &frames, &seconds) != 2 || seconds <= 0)
    throw std::runtime_error(cmd + " failed (status " + std::to_string(status) + "):\n" + text);
  std::filesystem::remove(out);
  return static_cast<double>(frames) / seconds;
}

struct StreamRun {
  double fps = 0, drawMs = 0, encodeMs = 0, allowed = 0;
  int width = 0, height = 0;
  std::string note;
};

// A live session of the scene playing for `seconds` with a viewer taking every frame; the stats'
// medians after the first two seconds (warm-up: shader compilation, the first window).
StreamRun streamRun(const std::shared_ptr<const Scene>& scene, const RatesOptions& o, int width, int height) {
  LiveConfig c;
  c.width = width;
  c.height = height;
  c.fps = o.streamFps;
  c.timeline = {0, 0};
  c.adaptSize = o.adaptSize;
  Look look;
  look.camera = chooseCamera(*scene, {});
  LiveSession s(scene, {{resolveSettings(*scene, {}), ""}}, look, c);
  LiveSession::Viewer viewer(s);
  s.play(1.0);
  std::vector<double> fps, draw, encode;
  const auto t0 = Clock::now();
  LiveFrame f;
  long long lastStats = 0;
  LiveStats st;
  while (secondsSince(t0) < o.streamSeconds) {
    f = s.waitFrame(f.seq, 1.0);
    st = s.stats();
    if (secondsSince(t0) > 2.0 && st.seq != lastStats && st.drawMs > 0 && st.encodeMs > 0) {
      lastStats = st.seq;
      fps.push_back(st.fps);
      draw.push_back(st.drawMs);
      encode.push_back(st.encodeMs);
    }
  }
  StreamRun r;
  r.fps = median(fps);
  r.drawMs = median(draw);
  r.encodeMs = median(encode);
  r.allowed = std::min<double>(o.streamFps, 1e3 / r.drawMs);
  r.width = st.width;
  r.height = st.height;
  r.note = st.sizeNote;
  return r;
}

struct SceneRates {
  std::vector<double> alone, video, streamFps, streamAllowed, encodeRatio;
  StreamRun lastStream;
};

const char* verdict(bool met) { return met ? "MET" : "NOT MET"; }

}  // namespace

int runRates(const RatesOptions& o, const std::vector<std::shared_ptr<const Scene>>& scenes, int width, int height) {
  const std::string substep = substepProgram(o.substep);
  const std::string folder = std::filesystem::temp_directory_path().string() + "/substep-rates." + std::to_string(getpid());
  std::filesystem::create_directories(folder);
  struct Cleanup {
    std::string dir;
    ~Cleanup() {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    }
  } cleanup{folder};

  std::printf("rates: %d rounds; video %g s at %d fps, %dx%d (%s render); stream %g s at %d fps asked%s\n", o.rounds,
              o.seconds, o.fps, width, height, substep.c_str(), o.streamSeconds, o.streamFps,
              o.adaptSize ? ", the size adapting" : ", the size fixed");
  std::vector<std::vector<DrawList>> lists;
  for (const auto& scene : scenes) lists.push_back(videoLists(scene, o.seconds, o.fps));
  std::vector<SceneRates> rates(scenes.size());
  for (int round = 1; round <= o.rounds; ++round) {
    for (size_t i = 0; i < scenes.size(); ++i) {
      SceneRates& r = rates[i];
      r.alone.push_back(drawAloneRate(lists[i], width, height));
      r.video.push_back(videoRate(substep, *scenes[i], o, folder));
      const StreamRun s = streamRun(scenes[i], o, width, height);
      r.streamFps.push_back(s.fps);
      r.streamAllowed.push_back(s.allowed);
      r.encodeRatio.push_back(s.encodeMs / s.drawMs);
      r.lastStream = s;
      std::printf("round %d  %-28s drawn alone %5.1f fps, video %5.1f fps (%.2fx); stream %4.1f fps of %4.1f allowed "
                  "(%.2fx) at %dx%d, draw %.1f ms, JPEG %.2f ms (%.2fx)\n",
                  round, std::filesystem::path(scenes[i]->file).filename().c_str(), r.alone.back(), r.video.back(),
                  r.video.back() / r.alone.back(), s.fps, s.allowed, s.fps / s.allowed, s.width, s.height, s.drawMs,
                  s.encodeMs, r.encodeRatio.back());
      std::fflush(stdout);
    }
  }
  bool all = true;
  std::printf("\nmedians over %d rounds\n", o.rounds);
  for (size_t i = 0; i < scenes.size(); ++i) {
    const SceneRates& r = rates[i];
    const double video = median(r.video), alone = median(r.alone), videoRatio = video / alone;
    const double deliver = median(r.streamFps) / median(r.streamAllowed), encode = median(r.encodeRatio);
    const bool v = videoRatio >= 0.9, d = deliver >= 0.9, e = encode <= 0.15;
    all = all && v && d && e;
    const std::string name = std::filesystem::path(scenes[i]->file).filename().string();
    std::printf("  %-28s video %5.1f fps / drawn alone %5.1f = %.2fx (at least 0.90x: %s)\n", name.c_str(), video, alone,
                videoRatio, verdict(v));
    std::printf("  %-28s stream %4.1f fps / allowed %4.1f = %.2fx (at least 0.90x: %s)\n", "", median(r.streamFps),
                median(r.streamAllowed), deliver, verdict(d));
    std::printf("  %-28s stream JPEG / draw = %.2fx (at most 0.15x: %s)%s%s\n", "", encode, verdict(e),
                r.lastStream.note.empty() ? "" : "; ", r.lastStream.note.c_str());
  }
  std::printf("all targets: %s\n", verdict(all));
  return all || !o.check ? 0 : kExitFailure;
}

}  // namespace substep::app

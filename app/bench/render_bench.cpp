// substep-render-bench: how long the renderer takes to draw a frame, on its own (no PNG encoding,
// no ffmpeg, no physics in the timed part). See docs/rendering.md, "Measured".
//
// Method: for each scene, a RenderSession (the one `substep render` uses) is stepped to --at
// outside the timing and its draw list built once (the scene's first camera, the HUD with the
// step cost measured on the way).
// A GlRenderer per setting (the command line's, or each --variant) draws --warmup frames that are
// not counted (shader compilation, first-use uploads), then --frames frames, each timed on its
// own with steady_clock around GlRenderer::render() into a reused image, the call `substep
// render` times as its draw time. With several variants the frames are interleaved (frame k of
// each, then k + 1), so a change in the machine's load falls on all alike. Reported: median, min,
// max and mean. Then, unless --split 0, --split frames more are drawn with a glFinish after every
// stage (shadow pass, scene, resolve with the sky under it, text, read-back, anti-aliasing with
// the row flip) and each stage's median is reported: those frames lose the overlap between stages
// (llvmpipe's threads rasterise one pass while the main thread prepares the next), so their sum
// can differ from the untimed median. The load average at start and end says how busy the
// machine was. Exit status: 0 done, 2 bad input, 3 a scene diverged, 1 other failures.
#include "app/bench/bench_stats.h"
#include "app/bench/render_rates.h"
#include "app/common.h"
#include "app/render_options.h"
#include "render/gl_renderer.h"
#include "render/image.h"
#include "render/session.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

namespace substep::app {
namespace {

using namespace substep::render;
using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) { return 1e3 * std::chrono::duration<double>(Clock::now() - t0).count(); }

// CPU time of the whole process [ms]: the main thread and llvmpipe's rasteriser threads. Less
// sensitive than wall-clock time to other work on a shared machine (though not immune: caches and
// the host's scheduling still count).
double cpuMs() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return 1e3 * static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_nsec);
}

struct Stats {
  double median = 0, min = 0, max = 0, mean = 0;
};

Stats stats(std::vector<double> v) {
  Stats s;
  if (v.empty()) return s;
  s.median = median(v);
  s.min = *std::min_element(v.begin(), v.end());
  s.max = *std::max_element(v.begin(), v.end());
  const size_t n = v.size();
  for (double x : v) s.mean += x / static_cast<double>(n);
  return s;
}

std::string loadText() {
  double l[3] = {0, 0, 0};
  if (getloadavg(l, 3) != 3) return "?";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.2f %.2f %.2f", l[0], l[1], l[2]);
  return buf;
}

struct Options {
  std::vector<std::string> scenes;
  double at = 2.0;
  int frames = 100, warmup = 5, split = 30, samples = -1, shadowSize = 1024;
  std::string size = "1280x720", aa, camera, save;
  std::vector<std::string> variants;
  bool noHud = false;
  bool rates = false;
  RatesOptions ratesOptions;
};

// A renderer setting to time: the command line's, or one --variant "samples=4,aa=none,shadow=1024".
struct Variant {
  std::string name;
  RendererOptions options;
};

Variant parseVariant(const std::string& text, const RendererOptions& base, bool aaGiven) {
  Variant v{text, base};
  size_t start = 0;
  while (!text.empty() && start <= text.size()) {
    const size_t end = std::min(text.find(',', start), text.size());
    const std::string item = text.substr(start, end - start);
    const size_t eq = item.find('=');
    const std::string key = item.substr(0, eq), value = eq == std::string::npos ? "" : item.substr(eq + 1);
    char* stop = nullptr;
    const long n = std::strtol(value.c_str(), &stop, 10);
    const bool number = !value.empty() && *stop == '\0';
    if (key == "samples" && number && (n == 1 || n == 2 || n == 4 || n == 8)) {
      v.options.samples = static_cast<int>(n);
    } else if (key == "shadow" && number && n >= 0 && n <= 8192) {
      v.options.shadowSize = static_cast<int>(n);
    } else if (key == "aa" && parseAntiAliasing(value)) {
      v.options.antiAliasing = *parseAntiAliasing(value);
      aaGiven = true;
    } else {
      throw UsageError("--variant \"" + text + "\": \"" + item +
                       "\" is not samples=1|2|4|8, shadow=0..8192 or aa=fxaa|none");
    }
    start = end + 1;
  }
  // As `substep render`: the filter without multisampling, multisampling alone, unless --aa says.
  if (!aaGiven) v.options.antiAliasing = v.options.samples > 1 ? AntiAliasing::None : AntiAliasing::Fxaa;
  return v;
}

// --- the plan ---------------------------------------------------------------------------------

// Every scene loaded, so that all are checked before any work.
std::vector<std::shared_ptr<const Scene>> loadScenes(const std::vector<std::string>& given) {
  std::vector<std::string> files = given;
  if (files.empty())
    files = {assetsDir() + "/scenes/pyramid.json", assetsDir() + "/scenes/pile.json",
             assetsDir() + "/scenes/ragdoll_pile.json"};
  std::vector<std::shared_ptr<const Scene>> scenes;
  for (const std::string& f : files) scenes.push_back(std::make_shared<const Scene>(load(f)));
  return scenes;
}

// Each --variant over the command line's renderer options; the command line's alone without one.
std::vector<Variant> variantsOf(const Options& o) {
  RendererOptions ro;
  if (o.samples > 0) ro.samples = o.samples;
  ro.shadowSize = o.shadowSize;
  if (!o.aa.empty()) ro.antiAliasing = *parseAntiAliasing(o.aa);  // CLI11 checked it
  std::vector<Variant> variants;
  for (const std::string& t : o.variants) variants.push_back(parseVariant(t, ro, !o.aa.empty()));
  if (variants.empty()) variants.push_back(parseVariant("", ro, !o.aa.empty()));
  return variants;
}

void printHeader(const Options& o, int width, int height) {
  const char* threads = std::getenv("LP_NUM_THREADS");
  std::cout << "substep-render-bench  " << width << "x" << height << ", " << o.frames << " frames after " << o.warmup
            << " warm-up, stages over " << o.split << " frames; LP_NUM_THREADS=" << (threads ? threads : "unset (2)")
            << "\nload average at start: " << loadText() << "\n";
}

RenderSession sceneSession(const std::shared_ptr<const Scene>& scene, const Options& o) {
  CameraOptions co;
  co.preset = o.camera;
  Look look;
  try {
    look.camera = chooseCamera(*scene, co);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  look.view.hud = !o.noHud;
  look.stepCost = true;  // as `substep render` draws it; the list is built once, so every frame draws the same text
  return RenderSession(scene, {{resolveSettings(*scene, SolverOverrides{}), ""}}, look);
}

// --- the timing -------------------------------------------------------------------------------

// A variant's renderer and what its frames took [ms].
struct VariantRun {
  std::unique_ptr<GlRenderer> renderer;
  Image img;
  double firstMs = 0, cpuMs = 0;
  long long blended = 0;
  std::vector<double> total, shadow, pass, resolve, text, readback, aa, sum;
};

// A renderer per variant, its first frame timed and the rest of the warm-up drawn.
std::vector<VariantRun> startRenderers(const std::vector<Variant>& variants, const std::vector<View>& views, int warmup,
                                       int width, int height) {
  std::vector<VariantRun> runs(variants.size());
  for (size_t i = 0; i < variants.size(); ++i) {
    runs[i].renderer = std::make_unique<GlRenderer>(width, height, variants[i].options);
    const auto f0 = Clock::now();
    runs[i].renderer->render(views, runs[i].img);
    runs[i].firstMs = msSince(f0);
    for (int k = 1; k < warmup; ++k) runs[i].renderer->render(views, runs[i].img);
  }
  return runs;
}

// Frame k of every variant, then k + 1, so that a change in the machine's load falls on every variant alike.
void timeFrames(std::vector<VariantRun>& runs, const std::vector<View>& views, int frames) {
  for (int k = 0; k < frames; ++k)
    for (VariantRun& r : runs) {
      const auto t0 = Clock::now();
      const double c0 = cpuMs();
      r.renderer->render(views, r.img);
      r.cpuMs += cpuMs() - c0;
      r.total.push_back(msSince(t0));
    }
}

void timeStages(std::vector<VariantRun>& runs, const std::vector<View>& views, int frames) {
  for (int k = 0; k < frames; ++k)
    for (VariantRun& r : runs) {
      FrameTimings t;
      r.renderer->render(views, r.img, &t);
      r.shadow.push_back(1e3 * t.shadow);
      r.pass.push_back(1e3 * t.scene);
      r.resolve.push_back(1e3 * t.resolve);
      r.text.push_back(1e3 * t.text);
      r.readback.push_back(1e3 * t.readback);
      r.aa.push_back(1e3 * t.antiAliasing);
      r.blended = t.blendedPixels;
      r.sum.push_back(1e3 * t.total());
    }
}

// --- the report -------------------------------------------------------------------------------

void saveFrame(const Options& o, const Scene& scene, size_t i, size_t variants, const Image& img) {
  std::string name = o.save + "/" + std::filesystem::path(scene.file).stem().string();
  if (variants > 1) name += "_" + std::to_string(i + 1);
  writePng(name + ".png", img);
}

void printStages(const VariantRun& r, int split) {
  auto line = [](const char* name, const std::vector<double>& v) {
    const Stats s = stats(v);
    std::printf("    %-10s median %.2f ms  min %.2f  max %.2f\n", name, s.median, s.min, s.max);
  };
  std::printf("  stages, each ended with glFinish (%d frames):\n", split);
  line("shadow", r.shadow);
  line("scene", r.pass);
  line("resolve", r.resolve);
  line("text", r.text);
  line("read-back", r.readback);
  line("fxaa/flip", r.aa);
  if (r.blended > 0) std::printf("    (the filter blended %lld pixels)\n", r.blended);
  line("sum", r.sum);
}

void printVariant(const Variant& v, const VariantRun& r, const Options& o) {
  const Stats st = stats(r.total);
  if (!v.name.empty()) std::printf("  variant    %s\n", v.name.c_str());
  std::printf("  renderer   %s, shadow map %d\n", r.renderer->glInfo().c_str(), v.options.shadowSize);
  std::printf("  first      %.2f ms (shader compilation, uploads)\n", r.firstMs);
  std::printf("  frame      median %.2f ms  min %.2f  max %.2f  mean %.2f  (%d frames)\n", st.median, st.min, st.max,
              st.mean, o.frames);
  std::printf("  cpu        %.2f ms a frame, all threads (mean)\n", r.cpuMs / o.frames);
  if (o.split > 0) printStages(r, o.split);
}

// One scene: stepped to --at and its draw list built outside the timing, then every variant timed.
// 0, or kExitNonFinite when the scene diverged.
int benchScene(const std::shared_ptr<const Scene>& shared, const Options& o, const std::vector<Variant>& variants, int width,
               int height) {
  const Scene& scene = *shared;
  RenderSession session = sceneSession(shared, o);
  const auto s0 = Clock::now();
  session.advanceTo(o.at);
  if (const Panel* p = session.firstDiverged()) {
    std::cerr << "substep-render-bench: " << scene.file << ": " << p->problem() << "\n";
    return kExitNonFinite;
  }
  const State& state = session.panel(0).state();
  const double stepMs = msSince(s0) / std::max<long long>(1, state.step);
  const auto b0 = Clock::now();
  const DrawList list = session.drawList(0);
  const double buildMs = msSince(b0);
  const std::vector<View> views = {View{&list, Viewport{0, 0, width, height}}};
  std::vector<VariantRun> runs = startRenderers(variants, views, o.warmup, width, height);
  timeFrames(runs, views, o.frames);
  timeStages(runs, views, o.split);
  std::printf("\n%s: %d dynamic bodies at t = %.2f s (%lld steps, %.2f ms each); draw list %.2f ms\n",
              scene.file.c_str(), scene.model.dynamicCount(), state.time, static_cast<long long>(state.step), stepMs,
              buildMs);
  for (size_t i = 0; i < runs.size(); ++i) {
    if (!o.save.empty()) saveFrame(o, scene, i, runs.size(), runs[i].img);
    printVariant(variants[i], runs[i], o);
  }
  return 0;
}

int run(const Options& o) {
  int width = 0, height = 0;
  parseFrameSize(o.size, width, height);
  if (o.rates) {
    RatesOptions r = o.ratesOptions;
    r.size = std::to_string(width) + "x" + std::to_string(height);
    std::vector<std::string> files = o.scenes;
    if (files.empty()) files = {assetsDir() + "/scenes/pyramid.json", assetsDir() + "/scenes/ragdoll_pile.json"};
    std::cout << "substep-render-bench --rates\nload average at start: " << loadText() << "\n";
    const int status = runRates(r, loadScenes(files), width, height);
    std::cout << "load average at end: " << loadText() << "\n";
    return status;
  }
  const std::vector<std::shared_ptr<const Scene>> scenes = loadScenes(o.scenes);
  const std::vector<Variant> variants = variantsOf(o);
  printHeader(o, width, height);
  for (const std::shared_ptr<const Scene>& scene : scenes)
    if (const int status = benchScene(scene, o, variants, width, height)) return status;
  std::cout << "\nload average at end: " << loadText() << "\n";
  return 0;
}

}  // namespace
}  // namespace substep::app

int main(int argc, char** argv) {
  using namespace substep::app;
  Options o;
  CLI::App app{
      "substep-render-bench: the renderer's time per frame, on its own (no PNG, no ffmpeg, no physics in the timing).\n"
      "Steps each scene to --at, builds its draw list once and draws it --frames times; prints median, min and max,\n"
      "and the stages (shadow, scene, resolve, text, read-back, anti-aliasing) of --split more frames each ended\nwith glFinish.\n"
      "llvmpipe's threads: LP_NUM_THREADS (2 when unset)."};
  app.add_option("scenes", o.scenes, "Scene files (default: assets/scenes/pyramid.json, pile.json and ragdoll_pile.json)")
      ->check(CLI::ExistingFile);
  app.add_option("--at", o.at, "Simulated time to step each scene to before drawing [s] (default 2)")
      ->check(CLI::Range(0.0, 1e4));
  app.add_option("--frames", o.frames, "Timed frames per scene (default 100)")->check(CLI::Range(1, 1000000));
  app.add_option("--warmup", o.warmup, "Frames drawn first and not counted (default 5)")->check(CLI::Range(1, 10000));
  app.add_option("--split", o.split, "Frames timed stage by stage, 0 for none (default 30)")->check(CLI::Range(0, 1000000));
  app.add_option("--size", o.size, "Frame size WIDTHxHEIGHT (default 1280x720)");
  app.add_option("--samples", o.samples, "Multisampling per pixel: 1 (off, the default), 2, 4 or 8 (llvmpipe draws 4)")
      ->check(CLI::IsMember({1, 2, 4, 8}));
  app.add_option("--aa", o.aa, "Post-process anti-aliasing: fxaa or none (default fxaa, none with --samples)")
      ->check(CLI::IsMember({"fxaa", "none"}));
  app.add_option("--shadow-size", o.shadowSize, "Shadow map side in texels, 0 for no shadows (default 1024)")
      ->check(CLI::Range(0, 8192));
  app.add_option("--camera", o.camera, "Camera preset of the scene files (default: each one's first)");
  app.add_flag("--no-hud", o.noHud, "No text");
  app.add_option("--variant", o.variants,
                 "Time several settings in one run, frames interleaved, e.g. --variant samples=4,aa=none "
                 "--variant samples=1,aa=fxaa,shadow=512 (keys samples, aa, shadow)");
  app.add_option("--save", o.save, "Also write each scene's last frame to this folder as SCENE.png")
      ->check(CLI::ExistingDirectory);
  RatesOptions& r = o.ratesOptions;
  app.add_flag("--rates", o.rates,
               "Instead: the video's and the stream's frame rates against the drawing alone, in rounds, with the targets' "
               "verdicts (scenes default to pyramid.json and ragdoll_pile.json)");
  app.add_option("--rounds", r.rounds, "--rates: rounds, each measuring every scene (default 3)")->check(CLI::Range(1, 100));
  app.add_option("--seconds", r.seconds, "--rates: simulated seconds of each video (default 5)")->check(CLI::Range(0.1, 600.0));
  app.add_option("--fps", r.fps, "--rates: the video's frames per second (default 60)")->check(CLI::Range(1, 240));
  app.add_option("--stream-seconds", r.streamSeconds, "--rates: wall seconds of each live session, 2 of them warm-up (default 8)")
      ->check(CLI::Range(3.0, 600.0));
  app.add_option("--stream-fps", r.streamFps, "--rates: the rate asked of the live session (default 30, serve's)")
      ->check(CLI::Range(1, 60));
  app.add_flag("!--fixed-size", r.adaptSize, "--rates: the live session keeps its size (default: it lowers it when the drawing cannot keep up)");
  app.add_flag("--check", r.check, "--rates: exit status 1 when a target is not met");
  app.add_option("--substep", r.substep, "--rates: the substep program (default: the one beside this one)");
  return runCommandLine(app, argc, argv, "substep-render-bench", [&] { return run(o); });
}

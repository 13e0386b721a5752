// substep render: steps a scene (or the same scene under two to four settings) and draws it
// off-screen: one PNG, a numbered PNG sequence, or an H.264 video through ffmpeg.
#include "app/commands.h"
#include "app/common.h"
#include "physics/world.h"
#include "render/compare.h"
#include "render/gl_renderer.h"
#include "render/scene_builder.h"
#include "render/video.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>

namespace substep::app {

namespace {

namespace fs = std::filesystem;
using namespace substep::render;

constexpr int kMaxWidth = 7680, kMaxHeight = 4320, kMinSide = 16;

struct RenderCmdOptions {
  std::string scene, output, compare, size = "1280x720", colour = "auto", camera;
  std::optional<std::string> follow;
  SolverOptions solver;
  std::optional<double> seconds, at, yaw, pitch, distance, fov;
  std::vector<double> target;
  std::vector<std::string> highlight;
  double orbit = 0, speedScale = 5, errorScale = 0.01;
  int fps = 60, samples = 1, shadowSize = 1024, crf = 18;
  std::optional<std::string> antiAliasing;  // --aa; default fxaa without multisampling, none with it
  std::string encoderPreset = "veryfast";
  bool contacts = false, joints = false, noHud = false, quiet = false;
};

enum class OutputKind { Png, Folder, Video };

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

OutputKind outputKind(const std::string& out) {
  if (out.empty()) throw UsageError("-o: expected a file name (.png, .mp4) or a folder, got nothing");
  const std::string ext = lower(fs::path(out).extension().string());
  if (ext == ".png") return OutputKind::Png;
  if (ext == ".mp4") return OutputKind::Video;
  std::error_code ec;
  if (out.back() == '/' || ext.empty() || fs::is_directory(out, ec)) return OutputKind::Folder;
  throw UsageError("-o " + out + ": cannot tell what to write from \"" + ext +
                   "\"; use a name ending in .png (one frame), .mp4 (H.264 video) or a folder (PNG sequence)");
}

// A whole number of up to six digits, or -1.
int smallNumber(const std::string& s) {
  if (s.empty() || s.size() > 6 || !std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return -1;
  return std::stoi(s);
}

void parseSize(const std::string& s, int& w, int& h) {
  const size_t x = s.find('x');
  w = x == std::string::npos ? -1 : smallNumber(s.substr(0, x));
  h = x == std::string::npos ? -1 : smallNumber(s.substr(x + 1));
  if (w < 0 || h < 0) throw UsageError("--size: expected WIDTHxHEIGHT, e.g. 1280x720, got \"" + s + "\"");
  if (w < kMinSide || h < kMinSide || w > kMaxWidth || h > kMaxHeight)
    throw UsageError("--size " + s + ": width must be " + std::to_string(kMinSide) + " to " + std::to_string(kMaxWidth) +
                     " and height " + std::to_string(kMinSide) + " to " + std::to_string(kMaxHeight) + " pixels (at most " +
                     std::to_string(kMaxWidth) + "x" + std::to_string(kMaxHeight) + ")");
}

// Ctrl-C stops at the next frame, so the temporary outputs are removed on the way out.
volatile std::sig_atomic_t gInterrupted = 0;
extern "C" void onInterrupt(int) { gInterrupted = 1; }

struct NonFinite : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A numbered PNG sequence, written into a sibling folder and moved into place when complete.
class FrameFolder {
 public:
  explicit FrameFolder(const std::string& out) {
    std::string trimmed = out;
    while (trimmed.size() > 1 && trimmed.back() == '/') trimmed.pop_back();
    dir_ = trimmed;
    stage_ = trimmed + ".part" + std::to_string(getpid());
    checkWritable(stage_, "-o " + out);
    std::error_code ec;
    if (fs::exists(dir_, ec) && !fs::is_directory(dir_, ec)) throw UsageError("-o " + out + ": exists and is not a folder");
    fs::create_directory(stage_, ec);
    if (ec) throw UsageError("-o " + out + ": cannot create " + stage_ + ": " + ec.message());
  }
  ~FrameFolder() {
    std::error_code ec;
    if (!committed_) fs::remove_all(stage_, ec);
  }
  static std::string name(long long k) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "frame_%05lld.png", k);
    return buf;
  }
  void write(long long k, const Image& img) {
    writePng(stage_ + "/" + name(k), img);
    ++count_;
  }
  void commit() {
    std::error_code ec;
    fs::create_directories(dir_, ec);
    if (ec) throw std::runtime_error(dir_ + ": cannot create the folder: " + ec.message());
    // Frames of an earlier, longer render would make the sequence look longer than it is.
    for (const auto& e : fs::directory_iterator(dir_, ec)) {
      const std::string f = e.path().filename().string();
      if (f.size() >= 15 && f.compare(0, 6, "frame_") == 0 && f.compare(f.size() - 4, 4, ".png") == 0) {
        const std::string digits = f.substr(6, f.size() - 10);
        if (digits.size() <= 12 && std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; }) &&
            std::stoll(digits) >= count_)
          fs::remove(e.path(), ec);
      }
    }
    for (long long k = 0; k < count_; ++k) {
      fs::rename(stage_ + "/" + name(k), dir_ + "/" + name(k), ec);
      if (ec) throw std::runtime_error(dir_ + ": cannot move " + name(k) + " into place: " + ec.message());
    }
    fs::remove_all(stage_, ec);
    committed_ = true;
  }

 private:
  std::string dir_, stage_;
  long long count_ = 0;
  bool committed_ = false;
};

// One simulation of the scene and what its panel shows.
struct Panel {
  std::string spec;           // --compare text, empty for a single view
  SolverSettings settings;
  std::unique_ptr<World> world;
  double costSum = 0;         // [s] of the steps since the last frame
  int costSteps = 0;
  double lastCostMs = std::numeric_limits<double>::quiet_NaN();
  double physicsSeconds = 0;
  long long steps = 0;
};

// Steps a panel's world until its time is the nearest step to t.
void advance(Panel& p, double t) {
  const double dt = p.settings.dt;
  while (p.world->state().time + 0.5 * dt <= t) {
    const StepReport& r = p.world->step();
    if (!r.finite)
      throw NonFinite((p.spec.empty() ? std::string() : "panel \"" + p.spec + "\": ") + "the simulation diverged at step " +
                      std::to_string(p.world->state().step) + " (t = " + std::to_string(p.world->state().time) +
                      " s): " + r.problem);
    p.costSum += r.times.total();
    p.physicsSeconds += r.times.total();
    ++p.costSteps;
    ++p.steps;
  }
  if (p.costSteps > 0) p.lastCostMs = 1e3 * p.costSum / p.costSteps;
  p.costSum = 0;
  p.costSteps = 0;
}

}  // namespace

void addRenderCommand(CLI::App& app, std::function<int()>& action) {
  auto opt = std::make_shared<RenderCmdOptions>();
  CLI::App* cmd = app.add_subcommand("render", "Step a scene and draw it off-screen: a PNG, a PNG sequence or an MP4");
  cmd->footer(
      "\nOutputs: -o x.png writes the frame at --at; -o a folder a numbered PNG sequence; -o x.mp4 H.264 video\n"
      "(ffmpeg, libx264, yuv420p). Physics steps at its own dt; frames are taken at --fps.\n"
      "Comparisons: --compare a2:m=4,a5:n=4 draws the scene under each setting in a grid (2 to 4 panels);\n"
      "settings after the algorithm are key=value separated by ':' (keys n, m, kappa, tau, omega, dt,\n"
      "tolerance, slop, preset, warm, block); other solver options apply to every panel.");
  cmd->add_option("scene", opt->scene, "Scene file (JSON), e.g. assets/scenes/pyramid.json")->required();
  cmd->add_option("-o,--output", opt->output, "Output: FILE.png (one frame), FILE.mp4 (video) or a folder (PNG sequence)")
      ->required();
  opt->solver.add(*cmd);
  auto* seconds = cmd->add_option("--seconds", opt->seconds, "Length of a video or sequence, simulated [s] (default 10)")
                      ->check(CLI::Range(1e-6, 1e5));
  auto* at = cmd->add_option("--at", opt->at, "Simulated time of a single PNG frame [s] (default 0)")
                 ->check(CLI::Range(0.0, 1e5));
  at->excludes(seconds);
  cmd->add_option("--fps", opt->fps, "Frames per simulated second (default 60)")->check(CLI::Range(1, 240));
  cmd->add_option("--size", opt->size, "Frame size WIDTHxHEIGHT (default 1280x720, at most 7680x4320)");
  auto* compare = cmd->add_option("--compare", opt->compare,
                                  "Draw 2-4 settings side by side, e.g. a2:m=4,a5:n=4 (see below)");
  cmd->get_option("--algo")->excludes(compare);
  cmd->add_option("--camera", opt->camera, "Camera preset of the scene file (default: its first, else a fitted view)");
  cmd->add_option("--yaw", opt->yaw, "Camera yaw about +Y [degrees], 0 looks along -Z");
  cmd->add_option("--pitch", opt->pitch, "Camera pitch above the horizon [degrees]")->check(CLI::Range(-89.0, 89.0));
  cmd->add_option("--distance", opt->distance, "Camera distance from its target [m]")->check(CLI::Range(1e-3, 1e5));
  cmd->add_option("--fov", opt->fov, "Vertical field of view [degrees]")->check(CLI::Range(5.0, 150.0));
  cmd->add_option("--target", opt->target, "Camera target x,y,z [m]")->expected(3)->delimiter(',');
  cmd->add_option("--follow", opt->follow, "Keep this body at the centre of the view");
  cmd->add_option("--orbit", opt->orbit, "Turn the camera about the target [degrees per simulated second]");
  cmd->add_option("--color,--colour", opt->colour,
                  "Body colours: auto (groups, else bodies), body, group, speed, activity (resting or moving), error "
                  "(constraint error)");
  cmd->add_option("--speed-scale", opt->speedScale, "--color speed: the speed drawn red [m/s] (default 5)")
      ->check(CLI::Range(1e-9, 1e9));
  cmd->add_option("--error-scale", opt->errorScale, "--color error: the error drawn red [m] (default 0.01)")
      ->check(CLI::Range(1e-12, 1e9));
  cmd->add_option("--highlight", opt->highlight, "Bodies to draw with a glow (names, comma separated)")->delimiter(',');
  cmd->add_flag("--contacts", opt->contacts, "Draw contact points and normals");
  cmd->add_flag("--joints", opt->joints, "Draw joint anchors, arms and axes");
  cmd->add_flag("--no-hud", opt->noHud, "No text overlay");
  cmd->add_option("--aa", opt->antiAliasing,
                  "Post-process anti-aliasing: fxaa (FXAA edge blend, the default) or none (the default with --samples)")
      ->check(CLI::IsMember({"fxaa", "none"}));
  cmd->add_option("--samples", opt->samples,
                  "Multisampling per pixel: 1 (off, the default), or 2, 4, 8 (llvmpipe draws 4: slower, finest edges)")
      ->check(CLI::IsMember({1, 2, 4, 8}));
  cmd->add_option("--shadow-size", opt->shadowSize, "Shadow map side in texels, 0 for no shadows (default 1024)")
      ->check(CLI::Range(0, 8192));
  cmd->add_option("--crf", opt->crf, "Video quality, x264 CRF: 0 lossless .. 51 worst (default 18)")->check(CLI::Range(0, 51));
  cmd->add_option("--encoder-preset", opt->encoderPreset, "x264 preset (default veryfast)")
      ->check(CLI::IsMember({"ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower"}));
  cmd->add_flag("--quiet,-q", opt->quiet, "Print nothing but errors");

  cmd->callback([opt, &action] {
    action = [opt]() -> int {
      const RenderCmdOptions& o = *opt;
      // Everything the user gave is checked before any work.
      int width = 0, height = 0;
      parseSize(o.size, width, height);
      const OutputKind kind = outputKind(o.output);
      if (kind == OutputKind::Png && o.seconds)
        throw UsageError("--seconds: a .png output is one frame; give its time with --at, or write .mp4 or a folder");
      if (kind != OutputKind::Png && o.at)
        throw UsageError("--at: only for a single .png frame; videos and sequences run from 0 for --seconds");
      if (kind == OutputKind::Video && (width % 2 || height % 2))
        throw UsageError("--size " + o.size + ": H.264 (yuv420p) needs an even width and height");
      const auto colour = parseColourMode(o.colour);
      if (!colour)
        throw UsageError("--color: expected auto, body, group, speed, activity or error, got \"" + o.colour + "\"");
      std::string ffmpeg;
      if (kind == OutputKind::Video) {
        ffmpeg = findFfmpeg();
        if (ffmpeg.empty())
          throw UsageError("-o " + o.output + ": writing MP4 needs the ffmpeg program, which is not " +
                           (std::getenv("SUBSTEP_FFMPEG") ? std::string("at $SUBSTEP_FFMPEG") : "on PATH") +
                           " (Debian: apt-get install ffmpeg), or write PNG frames to a folder instead");
      }

      const Scene scene = load(o.scene);
      CameraOptions camOpts;
      camOpts.preset = o.camera;
      camOpts.yaw = o.yaw;
      camOpts.pitch = o.pitch;
      camOpts.distance = o.distance;
      camOpts.fov = o.fov;
      if (!o.target.empty()) camOpts.target = Vec3(o.target[0], o.target[1], o.target[2]);
      camOpts.follow = o.follow;
      camOpts.orbit = o.orbit;
      CameraPreset camera;
      try {
        camera = chooseCamera(scene, camOpts);
      } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
      }
      for (const std::string& name : o.highlight)
        if (scene.model.bodyIndex(name) < 0)
          throw UsageError("--highlight: " + scene.file + " has no body \"" + name + "\"");

      // The panels: one, or one per --compare setting over the shared command-line settings.
      const SolverOverrides common = o.solver.overrides();
      std::vector<Panel> panels;
      if (o.compare.empty()) {
        panels.emplace_back();
        panels.back().settings = resolveSettings(scene, common);
      } else {
        std::vector<CompareSpec> specs;
        try {
          specs = parseCompareSpecs(o.compare);
        } catch (const std::invalid_argument& e) {
          throw UsageError(e.what());
        }
        for (const CompareSpec& s : specs) {
          panels.emplace_back();
          panels.back().spec = s.text;
          try {
            panels.back().settings = resolveSettings(scene, common.merged(s.overrides));
          } catch (const UsageError& e) {
            throw UsageError("--compare \"" + s.text + "\": " + e.what());
          }
        }
      }
      for (Panel& p : panels) {
        try {
          p.world = std::make_unique<World>(scene.model, p.settings, scene.initial);
        } catch (const std::invalid_argument& e) {
          throw UsageError((p.spec.empty() ? std::string() : "--compare \"" + p.spec + "\": ") + e.what());
        }
      }

      const double seconds = o.seconds.value_or(10.0);
      const long long frames = kind == OutputKind::Png ? 1 : std::max(1LL, std::llround(seconds * o.fps));
      ViewOptions view;
      view.colour = *colour;
      view.contacts = o.contacts;
      view.joints = o.joints;
      view.hud = !o.noHud;
      view.highlight = o.highlight;
      view.speedScale = o.speedScale;
      view.errorScale = o.errorScale;

      if (!o.quiet) {
        std::cout << "scene     " << scene.file << " (" << scene.model.dynamicCount() << " dynamic bodies, "
                  << scene.model.joints.size() << " joints)\n";
        for (const Panel& p : panels) std::cout << "solver    " << describe(p.settings) << "\n";
      }

      std::signal(SIGINT, onInterrupt);
      std::signal(SIGTERM, onInterrupt);
      // Draw time apart from the first frame, which includes compiling the shaders.
      double renderSeconds = 0, firstDrawSeconds = 0, writeSeconds = 0;
      const double wall0 = nowSeconds();
      std::string info;
      try {
        std::unique_ptr<FrameFolder> folder;
        std::unique_ptr<AtomicFile> png;
        std::unique_ptr<VideoEncoder> video;
        std::string videoTemp;
        if (kind == OutputKind::Folder) folder = std::make_unique<FrameFolder>(o.output);
        if (kind == OutputKind::Png) png = std::make_unique<AtomicFile>(o.output);
        if (kind == OutputKind::Video) {
          checkWritable(o.output, "-o " + o.output);
          videoTemp = o.output + ".part" + std::to_string(getpid());
          VideoOptions vo;
          vo.fps = o.fps;
          vo.crf = o.crf;
          vo.preset = o.encoderPreset;
          try {
            video = std::make_unique<VideoEncoder>(ffmpeg, videoTemp, width, height, vo);
          } catch (const VideoError& e) {
            throw std::runtime_error(e.what());
          }
        }

        RendererOptions ro;
        ro.samples = o.samples;
        ro.antiAliasing = o.antiAliasing ? *parseAntiAliasing(*o.antiAliasing)
                                         : (o.samples > 1 ? AntiAliasing::None : AntiAliasing::Fxaa);
        ro.shadowSize = o.shadowSize;
        std::unique_ptr<GlRenderer> renderer;
        try {
          renderer = std::make_unique<GlRenderer>(width, height, ro);
        } catch (const RenderError& e) {
          throw std::runtime_error(std::string("cannot render: ") + e.what());
        }
        info = renderer->glInfo();
        const std::vector<Viewport> grid = gridLayout(width, height, static_cast<int>(panels.size()));
        const std::string sceneText = sceneLine(scene);

        // A single frame far into a run is mostly stepping: show progress over the steps then.
        const bool single = kind == OutputKind::Png;
        const double at = o.at.value_or(0.0);
        Progress progress(single ? "simulate" : "render", single ? 1 : frames);
        Image img;  // reused: a fresh 3.7 MB frame each time costs milliseconds in page faults
        for (long long k = 0; k < frames; ++k) {
          if (gInterrupted) throw std::runtime_error("interrupted; no output written");
          const double t = single ? at : static_cast<double>(k) / o.fps;
          if (single) {
            // Step in half-second chunks so the progress bar moves during a long simulation.
            const double dt = panels[0].settings.dt;
            Progress steps("simulate", std::max(1LL, std::llround(at / dt)));
            for (double tc = std::min(at, 0.5);; tc = std::min(at, tc + 0.5)) {
              if (gInterrupted) throw std::runtime_error("interrupted; no output written");
              for (Panel& p : panels) advance(p, tc);
              if (!o.quiet) steps.update(std::llround(tc / dt));
              if (tc >= at) break;
            }
            if (!o.quiet) steps.finish();
          } else {
            for (Panel& p : panels) advance(p, t);
          }
          std::vector<DrawList> lists;
          lists.reserve(panels.size());
          for (Panel& p : panels) {
            const State& s = p.world->state();
            HudInfo hud;
            if (p.spec.empty()) {
              hud.scene = sceneText;
              hud.settings = settingsLine(p.settings);
            }  // a comparison panel's label names its settings; the HUD keeps to time and cost
            hud.time = s.time;
            hud.stepMs = p.lastCostMs;
            const Camera cam = placeCamera(camera, scene.model, s, o.orbit);
            lists.push_back(buildDrawList(scene.model, s, &p.world->manifolds(), cam, view, hud));
            if (!p.spec.empty()) lists.back().label = shortSettingsLine(p.settings);
          }
          std::vector<View> views;
          for (size_t i = 0; i < lists.size(); ++i) views.push_back({&lists[i], grid[i]});
          const double r0 = nowSeconds();
          renderer->render(views, img);
          const double r1 = nowSeconds();
          (k == 0 ? firstDrawSeconds : renderSeconds) += r1 - r0;
          if (png) {
            const std::vector<uint8_t> bytes = encodePng(img);
            png->out().write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
          }
          if (folder) folder->write(k, img);
          if (video) {
            try {
              video->write(img);
            } catch (const VideoError& e) {
              throw std::runtime_error(e.what());
            }
          }
          writeSeconds += nowSeconds() - r1;
          if (!o.quiet && !single) progress.update(k + 1);
        }
        if (!o.quiet && !single) progress.finish();
        const double w0 = nowSeconds();
        if (png) png->commit();
        if (folder) folder->commit();
        if (video) {
          try {
            video->finish();
          } catch (const VideoError& e) {
            throw std::runtime_error(e.what());
          }
          std::error_code ec;
          fs::rename(videoTemp, o.output, ec);
          if (ec) {
            fs::remove(videoTemp, ec);
            throw std::runtime_error(o.output + ": cannot rename " + videoTemp + " into place: " + ec.message());
          }
        }
        writeSeconds += nowSeconds() - w0;
      } catch (const NonFinite& e) {
        std::signal(SIGINT, SIG_DFL);
        std::signal(SIGTERM, SIG_DFL);
        std::cerr << "substep render: stopped: " << e.what() << "; no output written\n";
        return kExitNonFinite;
      }
      std::signal(SIGINT, SIG_DFL);
      std::signal(SIGTERM, SIG_DFL);

      if (!o.quiet) {
        long long steps = 0;
        double physics = 0;
        for (const Panel& p : panels) steps += p.steps, physics += p.physicsSeconds;
        std::cout << std::fixed << std::setprecision(2);
        std::cout << "renderer  " << info << "\n"
                  << "frames    " << frames << " at " << width << "x" << height;
        if (kind != OutputKind::Png) std::cout << ", " << o.fps << " fps";
        std::cout << "; per frame: draw ";
        if (frames > 1) std::cout << 1e3 * renderSeconds / (frames - 1) << " ms (the first ";
        std::cout << 1e3 * firstDrawSeconds << " ms" << (frames > 1 ? ", with shader compilation)" : "")
                  << ", write " << 1e3 * writeSeconds / frames
                  << " ms\n"
                  << "physics   " << steps << " steps, " << (steps ? 1e3 * physics / steps : 0.0) << " ms per step\n"
                  << "wall      " << nowSeconds() - wall0 << " s\n"
                  << "wrote     " << o.output << "\n";
      }
      return 0;
    };
  });
}

}  // namespace substep::app

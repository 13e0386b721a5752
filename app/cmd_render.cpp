// substep render: steps a scene (or the same scene under two to four settings) and draws it
// off-screen: one PNG, a numbered PNG sequence, or an H.264 video through ffmpeg. The work is a
// RenderSession's (render/session.h); frames go to a FrameSink (render/frame_sink.h).
#include "app/commands.h"
#include "app/common.h"
#include "app/render_options.h"
#include "render/ahead.h"
#include "render/frame_sink.h"

#include <cctype>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>

namespace substep::app {

namespace {

namespace fs = std::filesystem;
using namespace substep::render;

struct RenderCmdOptions {
  RenderOptions draw;
  std::string output;
  std::optional<double> seconds, at;
  int fps = 60, crf = 18;
  std::string encoderPreset = "veryfast";
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

}  // namespace

void addRenderCommand(CLI::App& app, std::function<int()>& action) {
  auto opt = std::make_shared<RenderCmdOptions>();
  CLI::App* cmd = app.add_subcommand("render", "Step a scene and draw it off-screen: a PNG, a PNG sequence or an MP4");
  cmd->footer(
      "\nOutputs: -o x.png writes the frame at --at; -o a folder a numbered PNG sequence; -o x.mp4 H.264 video\n"
      "(ffmpeg, libx264, yuv420p). Physics steps at its own dt; frames are taken at --fps.\n"
      "Comparisons: --compare a2:m=4,a5:n=4 (or --panels) draws the scene under each setting in a grid (2 to 4\n"
      "panels); settings after the algorithm are key=value separated by ':' (keys n, m, kappa, tau, omega, dt,\n"
      "tolerance, slop, preset, warm, block); other solver options apply to every panel.");
  opt->draw.add(*cmd, "--compare,--panels", "1280x720")->required();
  cmd->add_option("-o,--output", opt->output, "Output: FILE.png (one frame), FILE.mp4 (video) or a folder (PNG sequence)")
      ->required();
  auto* seconds = cmd->add_option("--seconds", opt->seconds, "Length of a video or sequence, simulated [s] (default 10)")
                      ->check(CLI::Range(1e-6, 1e5));
  auto* at = cmd->add_option("--at", opt->at, "Simulated time of a single PNG frame [s] (default 0)")
                 ->check(CLI::Range(0.0, 1e5));
  at->excludes(seconds);
  cmd->add_option("--fps", opt->fps, "Frames per simulated second (default 60)")->check(CLI::Range(1, 240));
  cmd->add_option("--crf", opt->crf, "Video quality, x264 CRF: 0 lossless .. 51 worst (default 18)")->check(CLI::Range(0, 51));
  cmd->add_option("--encoder-preset", opt->encoderPreset, "x264 preset (default veryfast)")
      ->check(CLI::IsMember({"ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower"}));

  cmd->callback([opt, &action] {
    action = [opt]() -> int {
      const RenderCmdOptions& o = *opt;
      const RenderOptions& d = o.draw;
      // Everything the user gave is checked before any work.
      int width = 0, height = 0;
      parseFrameSize(d.size, width, height);
      const OutputKind kind = outputKind(o.output);
      if (kind == OutputKind::Png && o.seconds)
        throw UsageError("--seconds: a .png output is one frame; give its time with --at, or write .mp4 or a folder");
      if (kind != OutputKind::Png && o.at)
        throw UsageError("--at: only for a single .png frame; videos and sequences run from 0 for --seconds");
      if (kind == OutputKind::Video && (width % 2 || height % 2))
        throw UsageError("--size " + d.size + ": H.264 (yuv420p) needs an even width and height");
      d.colourMode();
      std::string ffmpeg;
      if (kind == OutputKind::Video) {
        ffmpeg = findFfmpeg();
        if (ffmpeg.empty())
          throw UsageError("-o " + o.output + ": writing MP4 needs the ffmpeg program, which is not " +
                           (std::getenv("SUBSTEP_FFMPEG") ? std::string("at $SUBSTEP_FFMPEG") : "on PATH") +
                           " (Debian: apt-get install ffmpeg), or write PNG frames to a folder instead");
      }
      RenderSession session = d.makeSession(std::make_shared<const Scene>(load(d.scene)), true);

      const double seconds = o.seconds.value_or(10.0);
      const long long frames = kind == OutputKind::Png ? 1 : std::max(1LL, std::llround(seconds * o.fps));
      d.printHeader(session);

      // Draw time apart from the first frame, which includes compiling the shaders.
      double renderSeconds = 0, firstDrawSeconds = 0, finishSeconds = 0, writeSeconds = 0, waitPhysics = 0,
             waitWriting = 0;
      const double wall0 = nowSeconds();
      std::string info;
      {
        InterruptGuard interrupts;
        std::unique_ptr<FrameSink> sink;
        try {
          if (kind == OutputKind::Png) {
            checkWritable(o.output, o.output);
            sink = std::make_unique<PngSink>(o.output);
          } else if (kind == OutputKind::Folder) {
            checkWritable(PngFolderSink::stagingPath(o.output), "-o " + o.output);
            sink = std::make_unique<PngFolderSink>(o.output);
          } else {
            checkWritable(o.output, "-o " + o.output);
            VideoOptions vo;
            vo.fps = o.fps;
            vo.crf = o.crf;
            vo.preset = o.encoderPreset;
            sink = std::make_unique<VideoSink>(ffmpeg, o.output, width, height, vo);
          }
        } catch (const OutputError& e) {
          throw UsageError(std::string("-o ") + e.what());
        }
        const std::unique_ptr<GlRenderer> renderer = d.makeRenderer(width, height);
        info = renderer->glInfo();
        if (kind == OutputKind::Png) {
          // A single frame far into a run is mostly stepping: show progress over the steps then.
          advanceShowingSteps(session, o.at.value_or(0.0), d.quiet);
          if (const Panel* p = session.firstDiverged()) return reportDivergence("substep render", *p);
          stopIfInterrupted();
          Image img;
          const double r0 = nowSeconds();
          renderer->render(gridViews(session.drawLists(), width, height), img);
          firstDrawSeconds = nowSeconds() - r0;
          const double w0 = nowSeconds();
          sink->write(img);
          sink->commit();
          writeSeconds = nowSeconds() - w0;
        } else {
          // Three threads: the physics steps ahead (render/ahead.h), this one draws, and the
          // frames drawn are anti-aliased and written (piped to ffmpeg, or encoded as PNG) beside
          // the drawing of the next.
          ThreadedSink out(std::move(sink));
          RawFrame raw;  // buffers go round between the threads: no page faults per frame
          std::vector<double> times(static_cast<size_t>(frames));
          for (long long k = 0; k < frames; ++k) times[static_cast<size_t>(k)] = static_cast<double>(k) / o.fps;
          SessionAhead ahead(session, std::move(times));
          Progress progress("render", frames);
          for (long long k = 0; k < frames; ++k) {
            stopIfInterrupted();
            const SessionAhead::Frame f = ahead.next();
            if (f.diverged) {
              ahead.stop();
              return reportDivergence("substep render", *session.firstDiverged());
            }
            const double r0 = nowSeconds();
            renderer->draw(gridViews(f.lists, width, height), raw);
            (k == 0 ? firstDrawSeconds : renderSeconds) += nowSeconds() - r0;
            out.pass(raw);
            if (!d.quiet) progress.update(k + 1);
          }
          if (!d.quiet) progress.finish();
          ahead.stop();
          out.commit();
          writeSeconds = out.writeSeconds();
          finishSeconds = out.finishSeconds();
          waitPhysics = ahead.waitedSeconds();
          waitWriting = out.waitedSeconds();
        }
      }
      const double wall = nowSeconds() - wall0;

      if (!d.quiet) {
        long long steps = 0;
        double physics = 0;
        for (int i = 0; i < session.panelCount(); ++i)
          steps += session.panel(i).steps(), physics += session.panel(i).physicsSeconds();
        std::cout << std::fixed << std::setprecision(2);
        std::cout << "renderer  " << info << "\n"
                  << "frames    " << frames << " at " << width << "x" << height;
        if (kind == OutputKind::Png) {
          std::cout << "; draw " << 1e3 * firstDrawSeconds << " ms, write " << 1e3 * writeSeconds << " ms\n"
                    << "physics   " << steps << " steps, " << (steps ? 1e3 * physics / steps : 0.0) << " ms per step\n"
                    << "wall      " << wall << " s\n";
        } else {
          std::cout << ", " << o.fps << " fps\n"
                    << "per frame physics " << 1e3 * physics / frames << " ms (" << steps << " steps, "
                    << (steps ? 1e3 * physics / steps : 0.0) << " ms each), draw ";
          if (frames > 1) std::cout << 1e3 * renderSeconds / (frames - 1) << " ms (the first ";
          std::cout << 1e3 * firstDrawSeconds << " ms" << (frames > 1 ? ", with shader compilation)" : "")
                    << ", anti-aliasing " << 1e3 * finishSeconds / frames << " ms, write " << 1e3 * writeSeconds / frames
                    << " ms\n"
                    << "          on three threads: physics ahead of the drawing, anti-aliasing and writing beside it; the drawing waited "
                    << 1e3 * waitPhysics / frames << " ms for physics and " << 1e3 * waitWriting / frames
                    << " ms for the writing\n"
                    << "rate      " << frames << " frames in " << wall << " s: " << std::setprecision(1)
                    << frames / wall << " frames per second end to end (physics, drawing, "
                    << (kind == OutputKind::Video ? "encoding" : "PNG writing") << ")\n"
                    << std::setprecision(2);
        }
        std::cout << "wrote     " << o.output << "\n";
      }
      return 0;
    };
  });
}

}  // namespace substep::app

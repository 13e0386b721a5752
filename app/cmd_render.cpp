// substep render: steps a scene (or the same scene under two to four settings) and draws it
// off-screen: one PNG, a numbered PNG sequence, or an H.264 video through ffmpeg. The work is a
// RenderSession's (render/session.h); frames go to a FrameSink (render/frame_sink.h).
#include "app/commands.h"
#include "app/common.h"
#include "app/render_options.h"
#include "lab/record.h"
#include "physics/recording.h"
#include "physics/settings_json.h"
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
  std::optional<std::string> record;  // a recording of the panels' steps as they are drawn
  long long recordEvery = 1;
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

// --- the plan: what the options ask for, checked before any work ------------------------------

struct RenderPlan {
  OutputKind kind = OutputKind::Png;
  int width = 0, height = 0;
  std::string ffmpeg;   // for a video
  long long frames = 1;
};

// --seconds and --at each belong to one kind of output; H.264 (yuv420p) takes even sides only.
void checkOutputOptions(const RenderCmdOptions& o, const RenderPlan& p) {
  if (p.kind == OutputKind::Png && o.seconds)
    throw UsageError("--seconds: a .png output is one frame; give its time with --at, or write .mp4 or a folder");
  if (p.kind != OutputKind::Png && o.at)
    throw UsageError("--at: only for a single .png frame; videos and sequences run from 0 for --seconds");
  if (p.kind == OutputKind::Video && (p.width % 2 || p.height % 2))
    throw UsageError("--size " + o.draw.size + ": H.264 (yuv420p) needs an even width and height");
}

std::string videoEncoder(const std::string& output) {
  const std::string ffmpeg = findFfmpeg();
  if (ffmpeg.empty())
    throw UsageError("-o " + output + ": writing MP4 needs the ffmpeg program, which is not " +
                     (std::getenv("SUBSTEP_FFMPEG") ? std::string("at $SUBSTEP_FFMPEG") : "on PATH") +
                     " (Debian: apt-get install ffmpeg), or write PNG frames to a folder instead");
  return ffmpeg;
}

RenderPlan planRender(const RenderCmdOptions& o) {
  RenderPlan p;
  parseFrameSize(o.draw.size, p.width, p.height);
  p.kind = outputKind(o.output);
  checkOutputOptions(o, p);
  o.draw.colourMode();
  if (p.kind == OutputKind::Video) p.ffmpeg = videoEncoder(o.output);
  p.frames = p.kind == OutputKind::Png ? 1 : std::max(1LL, std::llround(o.seconds.value_or(10.0) * o.fps));
  return p;
}

// --- the frames -------------------------------------------------------------------------------

// Wall times of making the frames [s]; the first frame's draw apart, as it includes compiling the shaders.
struct FrameTimes {
  double draw = 0, firstDraw = 0, finish = 0, write = 0, waitPhysics = 0, waitWriting = 0, wall = 0;
  std::string glInfo;
};

std::unique_ptr<FrameSink> openSink(const RenderCmdOptions& o, const RenderPlan& p) {
  try {
    if (p.kind == OutputKind::Png) {
      checkWritable(o.output, o.output);
      return std::make_unique<PngSink>(o.output);
    }
    if (p.kind == OutputKind::Folder) {
      checkWritable(PngFolderSink::stagingPath(o.output), "-o " + o.output);
      return std::make_unique<PngFolderSink>(o.output);
    }
    checkWritable(o.output, "-o " + o.output);
    VideoOptions vo;
    vo.fps = o.fps;
    vo.crf = o.crf;
    vo.preset = o.encoderPreset;
    return std::make_unique<VideoSink>(p.ffmpeg, o.output, p.width, p.height, vo);
  } catch (const OutputError& e) {
    throw UsageError(std::string("-o ") + e.what());
  }
}

// The frame at --at: a single frame far into a run is mostly stepping, so progress is over the steps.
int writeStill(RenderSession& session, GlRenderer& renderer, FrameSink& sink, const RenderCmdOptions& o,
               const RenderPlan& p, FrameTimes& t) {
  advanceShowingSteps(session, o.at.value_or(0.0), o.draw.quiet);
  if (const Panel* d = session.firstDiverged()) return reportDivergence("substep render", *d);
  stopIfInterrupted();
  Image img;
  const double r0 = nowSeconds();
  renderer.render(gridViews(session.drawLists(), p.width, p.height), img);
  t.firstDraw = nowSeconds() - r0;
  const double w0 = nowSeconds();
  sink.write(img);
  sink.commit();
  t.write = nowSeconds() - w0;
  return 0;
}

// Frames at --fps from 0: three threads, the physics stepping ahead (render/ahead.h), this one
// drawing, and the frames drawn anti-aliased and written (piped to ffmpeg, or encoded as PNG)
// beside the drawing of the next.
int writeSequence(RenderSession& session, GlRenderer& renderer, std::unique_ptr<FrameSink> sink, const RenderCmdOptions& o,
                  const RenderPlan& p, FrameTimes& t) {
  ThreadedSink out(std::move(sink));
  RawFrame raw;  // buffers go round between the threads: no page faults per frame
  std::vector<double> times(static_cast<size_t>(p.frames));
  for (long long k = 0; k < p.frames; ++k) times[static_cast<size_t>(k)] = static_cast<double>(k) / o.fps;
  SessionAhead ahead(session, std::move(times));
  Progress progress("render", p.frames);
  for (long long k = 0; k < p.frames; ++k) {
    stopIfInterrupted();
    const SessionAhead::Frame f = ahead.next();
    if (f.diverged) {
      ahead.stop();
      return reportDivergence("substep render", *session.firstDiverged());
    }
    const double r0 = nowSeconds();
    renderer.draw(gridViews(f.lists, p.width, p.height), raw);
    (k == 0 ? t.firstDraw : t.draw) += nowSeconds() - r0;
    out.pass(raw);
    if (!o.draw.quiet) progress.update(k + 1);
  }
  if (!o.draw.quiet) progress.finish();
  ahead.stop();
  out.commit();
  t.write = out.writeSeconds();
  t.finish = out.finishSeconds();
  t.waitPhysics = ahead.waitedSeconds();
  t.waitWriting = out.waitedSeconds();
  return 0;
}

// The frames drawn into the output; 0, or the exit status of a diverged panel (nothing written).
int produceFrames(RenderSession& session, const RenderCmdOptions& o, const RenderPlan& p, FrameTimes& t) {
  InterruptGuard interrupts;
  std::unique_ptr<FrameSink> sink = openSink(o, p);
  const std::unique_ptr<GlRenderer> renderer = o.draw.makeRenderer(p.width, p.height);
  t.glInfo = renderer->glInfo();
  if (p.kind == OutputKind::Png) return writeStill(session, *renderer, *sink, o, p, t);
  return writeSequence(session, *renderer, std::move(sink), o, p, t);
}

// --- the report -------------------------------------------------------------------------------

struct PhysicsCost {
  long long steps = 0;
  double seconds = 0;
  double msPerStep() const { return steps ? 1e3 * seconds / steps : 0.0; }
};

PhysicsCost physicsCost(const RenderSession& session) {
  PhysicsCost c;
  for (int i = 0; i < session.panelCount(); ++i) c.steps += session.panel(i).steps(), c.seconds += session.panel(i).physicsSeconds();
  return c;
}

void printStillTimes(const PhysicsCost& c, const FrameTimes& t) {
  std::cout << "; draw " << 1e3 * t.firstDraw << " ms, write " << 1e3 * t.write << " ms\n"
            << "physics   " << c.steps << " steps, " << c.msPerStep() << " ms per step\n"
            << "wall      " << t.wall << " s\n";
}

void printSequenceTimes(const PhysicsCost& c, const FrameTimes& t, const RenderCmdOptions& o, const RenderPlan& p) {
  const long long frames = p.frames;
  std::cout << ", " << o.fps << " fps\n"
            << "per frame physics " << 1e3 * c.seconds / frames << " ms (" << c.steps << " steps, " << c.msPerStep()
            << " ms each), draw ";
  if (frames > 1) std::cout << 1e3 * t.draw / (frames - 1) << " ms (the first ";
  std::cout << 1e3 * t.firstDraw << " ms" << (frames > 1 ? ", with shader compilation)" : "") << ", anti-aliasing "
            << 1e3 * t.finish / frames << " ms, write " << 1e3 * t.write / frames << " ms\n"
            << "          on three threads: physics ahead of the drawing, anti-aliasing and writing beside it; the drawing waited "
            << 1e3 * t.waitPhysics / frames << " ms for physics and " << 1e3 * t.waitWriting / frames << " ms for the writing\n"
            << "rate      " << frames << " frames in " << t.wall << " s: " << std::setprecision(1) << frames / t.wall
            << " frames per second end to end (physics, drawing, "
            << (p.kind == OutputKind::Video ? "encoding" : "PNG writing") << ")\n"
            << std::setprecision(2);
}

void printReport(const RenderSession& session, const RenderCmdOptions& o, const RenderPlan& p, const FrameTimes& t) {
  const PhysicsCost c = physicsCost(session);
  std::cout << std::fixed << std::setprecision(2);
  std::cout << "renderer  " << t.glInfo << "\n"
            << "frames    " << p.frames << " at " << p.width << "x" << p.height;
  if (p.kind == OutputKind::Png)
    printStillTimes(c, t);
  else
    printSequenceTimes(c, t, o, p);
  std::cout << "wrote     " << o.output << "\n";
}

// The panels' steps into a recording as the session keeps them (on the stepping thread): every
// `every`-th, the first and the last.
class SessionRecorder {
 public:
  SessionRecorder(const std::string& path, RenderSession& session, long long every, long long plannedSteps)
      : every_(every), last_(static_cast<size_t>(session.panelCount()), -1) {
    std::vector<lab::RecordingPanel> panels;
    for (int i = 0; i < session.panelCount(); ++i)
      panels.push_back({session.panel(i).name(), settingsJson(session.panel(i).settings()), session.panel(i).name(), "substep"});
    try {
      writer_ = std::make_unique<RecordingWriter>(path, lab::recordingMeta(session.scene(), panels, every, plannedSteps));
    } catch (const RecordingError& e) {
      throw UsageError(std::string("--record ") + e.what());
    }
    session.setSnapshotHook([this](int panel, const std::shared_ptr<const Scene>&, const Snapshot& s) {
      if (s.state.step % every_ == 0) add(panel, s);
    });
  }
  // The panels' last steps, then the file; the error of a write that failed on the way.
  void commit(const RenderSession& session) {
    for (int i = 0; i < session.panelCount(); ++i) add(i, session.panel(i).shown());
    if (!error_.empty()) throw std::runtime_error("--record: " + error_);
    writer_->commit();
  }
  const RecordingWriter& writer() const { return *writer_; }

 private:
  void add(int panel, const Snapshot& s) {
    if (!error_.empty() || s.state.step <= last_[static_cast<size_t>(panel)]) return;
    try {
      writer_->add(panel, s);
      last_[static_cast<size_t>(panel)] = s.state.step;
    } catch (const std::exception& e) {  // a full disk: reported at the end, the frames go on
      error_ = e.what();
    }
  }
  long long every_;
  std::vector<long long> last_;  // per panel: the step written last
  std::unique_ptr<RecordingWriter> writer_;
  std::string error_;
};

int runRender(const RenderCmdOptions& o) {
  RenderPlan p = planRender(o);
  std::optional<OpenedRecording> rec;
  if (isRecordingPath(o.draw.scene)) {
    rec = openRecordingFile(o.draw.scene);
    // A recording's video covers the recording unless told otherwise.
    if (!o.seconds && p.kind != OutputKind::Png) p.frames = std::max(1LL, std::llround(rec->seconds * o.fps));
  }
  RenderSession session = rec ? o.draw.makeRecordedSession(*rec)
                              : o.draw.makeSession(std::make_shared<const Scene>(load(o.draw.scene)), true);
  std::unique_ptr<SessionRecorder> recorder;
  if (o.record) {
    if (rec) throw UsageError("--record: " + o.draw.scene + " is a recording already");
    if (o.record->empty()) throw UsageError("--record: expected a file name, got an empty one");
    if (samePath(*o.record, o.output)) throw UsageError("--record and -o name the same file " + o.output + "; give each its own");
    checkWritable(*o.record, "--record " + *o.record);
    const double seconds = p.kind == OutputKind::Png ? o.at.value_or(0.0) : static_cast<double>(p.frames) / o.fps;
    recorder = std::make_unique<SessionRecorder>(*o.record, session, o.recordEvery,
                                                 std::llround(seconds / session.panel(0).settings().dt));
  }
  o.draw.printHeader(session);
  FrameTimes t;
  const double wall0 = nowSeconds();
  const int status = produceFrames(session, o, p, t);
  // A diverged run's recording holds the steps before it: what there is to inspect.
  if (recorder) recorder->commit(session);
  if (status) return status;
  t.wall = nowSeconds() - wall0;
  if (!o.draw.quiet) printReport(session, o, p, t);
  if (recorder && !o.draw.quiet)
    std::cout << "wrote     " << *o.record << " (" << recorder->writer().frames() << " frames, " << std::fixed
              << std::setprecision(1) << static_cast<double>(recorder->writer().bytes()) / 1e6 << " MB)\n";
  return 0;
}

}  // namespace

void addRenderCommand(CLI::App& app, std::function<int()>& action) {
  auto opt = std::make_shared<RenderCmdOptions>();
  CLI::App* cmd = app.add_subcommand("render", "Step a scene and draw it off-screen: a PNG, a PNG sequence or an MP4");
  cmd->footer(
      "\nOutputs: -o x.png writes the frame at --at; -o a folder a numbered PNG sequence; -o x.mp4 H.264 video\n"
      "(ffmpeg, libx264, yuv420p). Physics steps at its own dt; frames are taken at --fps.\n"
      "Comparisons: --compare a2:m=4,a5:n=4 (or --panels) draws the scene under each setting in a grid (2 to 4\n"
      "panels); settings after the algorithm are key=value separated by ':' (any key or alias of `substep\n"
      "settings`); other solver options apply to every panel.\n"
      "Recordings: `substep render out/x.rec -o x.mp4` draws a recording (substep run --record) without stepping,\n"
      "with its own panels and settings (docs/recordings.md).");
  opt->draw.add(*cmd, "--compare,--panels", "1280x720")->required();
  cmd->add_option("-o,--output", opt->output, "Output: FILE.png (one frame), FILE.mp4 (video) or a folder (PNG sequence)")
      ->required();
  auto* seconds = cmd->add_option("--seconds", opt->seconds,
                                  "Length of a video or sequence, simulated [s] (default 10; a recording's: its length)")
                      ->check(CLI::Range(1e-6, 1e5));
  auto* at = cmd->add_option("--at", opt->at, "Simulated time of a single PNG frame [s] (default 0)")
                 ->check(CLI::Range(0.0, 1e5));
  at->excludes(seconds);
  cmd->add_option("--fps", opt->fps, "Frames per simulated second (default 60)")->check(CLI::Range(1, 240));
  cmd->add_option("--record", opt->record,
                  "Also write a recording of every panel's steps to this file (substep serve --open replays it; "
                  "docs/recordings.md)");
  cmd->add_option("--record-every", opt->recordEvery, "Keep every K-th step in the recording (first and last always)")
      ->check(CLI::Range(1LL, 1000000000LL));
  cmd->add_option("--crf", opt->crf, "Video quality, x264 CRF: 0 lossless .. 51 worst (default 18)")->check(CLI::Range(0, 51));
  cmd->add_option("--encoder-preset", opt->encoderPreset, "x264 preset (default veryfast)")
      ->check(CLI::IsMember({"ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower"}));

  cmd->callback([opt, &action] { action = [opt] { return runRender(*opt); }; });
}

}  // namespace substep::app

// A live session: a RenderSession played in real time on a thread of its own, for the server
// (`substep serve`). The thread owns the session's renderer (an OSMesa context is current on one
// thread at a time), steps the panels paced to the wall clock and draws a frame per tick while
// someone watches; a second thread encodes it as JPEG (while the next one is drawn) and
// publishes it with the stats of the step; the session keeps the
// last seconds of frames so that a clip of them can be made, and records clips of the next
// seconds. No HTTP here: app/server.cpp calls it from its request threads.
//
//   LiveSession s(scene, {{settings, ""}}, look, config);   // starts the thread, paused
//   s.play(1.0);
//   s.change([](RenderSession& r, Look& look) { look.camera.yaw += 10; });
//   LiveFrame f = s.waitFrame(0, 1.0);                        // the next JPEG
//
// Pacing: each tick (1/fps of wall time) the simulated time is meant to advance by speed times
// the wall time since the last tick. The physics of a tick may take at most `physicsBudget` of
// the tick; what it cannot do is dropped (the simulation falls behind real time, and the stats
// say so with the rate it achieves) rather than owed, so that a slow scene does not spiral.
#pragma once

#include "physics/scene_file.h"
#include "render/gl_renderer.h"
#include "render/session.h"

#include <atomic>
#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace substep::render {

// Turns at a resource many sessions share (the cores), in the order they were asked for, at most
// `slots` at once: llvmpipe draws one frame on both cores, so sessions that draw at the same time
// only slow each other down (8 sessions at 1280x720 drew 12 frames a second together without a
// gate, measured, and 15 to 18 with one; docs/server.md).
class FairGate {
 public:
  explicit FairGate(int slots) : slots_(slots) {}
  int waiting() const;  // tickets not yet served
  class Turn {
   public:
    explicit Turn(FairGate* g);
    ~Turn();
    Turn(const Turn&) = delete;
    Turn& operator=(const Turn&) = delete;
   private:
    FairGate* g_;
  };

 private:
  mutable std::mutex m_;
  std::condition_variable cv_;
  unsigned long long next_ = 0, head_ = 0;  // tickets handed out; the next one to go
  int slots_, busy_ = 0;
};

struct LiveConfig {
  int width = 1280, height = 720;
  int fps = 30;                 // frames per wall-clock second
  int jpegQuality = 80;
  double historySeconds = 10;   // frames kept for clips of the last seconds
  HistoryLimits timeline;       // the steps kept to scrub back to (RenderSession::view)
  double physicsBudget = 0.8;   // share of a tick the physics may take before it falls behind
  RendererOptions renderer;
  std::string ffmpeg;           // for clips; "" refuses them
  std::string clipFolder;       // where finished clips are written
  // Frames drawn smaller (3/4, then 1/2 of each side) while even the drawing alone cannot keep
  // the asked rate, larger again when the size above would; the stats say so (sizeNote).
  bool adaptSize = true;
  std::shared_ptr<FairGate> drawGate, encodeGate;  // shared by the sessions of a server; null: none
};

// One panel's measures after a tick.
struct LivePanelStats {
  std::string name, settings;   // the panel's label (its method spec) and settingsLine()
  double time = 0;              // simulated [s]
  long long steps = 0;
  double stepMs = 0;            // mean cost of the tick's steps [ms] (NaN before any)
  StageTimes stages;            // the last step's stages [s]
  int contacts = 0, manifolds = 0, pairs = 0;
  double penetration = 0, jointError = 0;  // [m]
  double kinetic = 0, potential = 0;       // [J]
  bool diverged = false;
  std::string problem;
  bool ended = false;           // diverged, or a recording at its end
};

struct LiveStats {
  long long seq = 0;            // increases with every tick that published
  long long frames = 0;         // frames drawn since the start
  bool playing = false, seeking = false;
  // The timeline: the kept span and what is shown [s]; live: the newest step is shown.
  double first = 0, last = 0, shown = 0;
  long long shownStep = 0;
  bool live = true, recorded = false;
  double speed = 1;             // asked: simulated seconds per wall second
  double achieved = 0;          // what the last second achieved (while playing)
  bool behind = false;          // playing slower than asked: the physics cannot keep up
  double fps = 0;               // frames drawn per wall second, over the last second
  double physicsMs = 0, drawMs = 0, encodeMs = 0;  // per tick, over the last second
  int jpegBytes = 0;
  int width = 0, height = 0;    // the frames' size as drawn: the config's, or less (adaptSize)
  std::string sizeNote;         // why they are drawn smaller; "" at the config's size
  std::vector<LivePanelStats> panels;
  std::string status;           // why it paused (a divergence), or a renderer failure
};

struct LiveFrame {
  long long seq = 0;            // 0: none (yet, or the session closed)
  std::shared_ptr<const std::string> jpeg;
  double time = 0;              // simulated, panel 0 [s]
};

// A clip of the session's frames, encoded to H.264 by ffmpeg on a thread of its own.
struct ClipInfo {
  int id = 0;
  std::string mode;             // "last" or "next"
  double seconds = 0;
  std::string state;            // "recording", "encoding", "done", "failed"
  int frames = 0;
  std::string error;
  std::string path;             // when done
  long long bytes = 0;
};

class LiveSession {
 public:
  // Starts the session's thread, paused at t = 0. Throws PanelError (as RenderSession does).
  LiveSession(std::shared_ptr<const Scene> scene, const std::vector<PanelSetup>& panels, const Look& look,
              const LiveConfig& config);
  ~LiveSession();  // close()
  LiveSession(const LiveSession&) = delete;
  LiveSession& operator=(const LiveSession&) = delete;

  // Stops the thread (after the step it is in), ends streams waiting on it, waits for clips
  // being encoded. Idempotent.
  void close();
  bool closed() const { return closed_; }
  const LiveConfig& config() const { return config_; }

  // Any change of the simulation or of what is drawn, under the session's lock, between steps;
  // the next tick draws it. What `f` throws propagates.
  template <class F>
  auto change(F&& f) {
    return apply(std::forward<F>(f), false);
  }
  // The same for a change that starts the panels again (other panels, another scene): from
  // t = 0 afterwards, a divergence forgotten, playing on if it played; when `f` throws (the
  // panels were left as they were), the play state stays too.
  template <class F>
  auto restart(F&& f) {
    return apply(std::forward<F>(f), true);
  }
  // Reading under the lock.
  template <class F>
  auto read(F&& f) const {
    std::lock_guard<std::mutex> lk(m_);
    return f(session_, look_);
  }

  // speed: simulated seconds per wall second; < 0 plays backwards through the kept steps (and
  // pauses at the first). Forward from a past step replays the kept steps, then steps on.
  void play(double speed);
  void pause();
  // `count` steps now, paused (the answer waits for them); count < 0 goes back through the kept
  // steps. Returns the simulated time shown.
  double step(int count);
  void reset();              // to t = 0, playing on if it played (a recording: to its start)
  // To simulated time t, paused: at once when the step is kept (scrubbing); forward by stepping as
  // fast as it can when t is later than the newest; from the start when t is earlier than the
  // first kept step.
  void seek(double t);
  void live();               // the newest step, paused
  bool playing() const;

  // The first frame newer than `after`, waiting up to `timeout` seconds for it; the latest frame
  // (maybe not newer) after the timeout; seq 0 when the session closed or none was ever drawn.
  // Waiting counts as watching: frames are drawn only while someone waits for them or a clip
  // records.
  LiveFrame waitFrame(long long after, double timeout);
  // The latest frame as pixels, drawing one if none is current (waits up to `timeout` seconds).
  std::shared_ptr<const Image> image(double timeout);
  // The first stats newer than `after`, or the latest after `timeout` seconds.
  LiveStats waitStats(long long after, double timeout) const;
  LiveStats stats() const;

  // A stream of the session counts as a viewer while it lives.
  class Viewer {
   public:
    explicit Viewer(LiveSession& s) : s_(s) { ++s_.viewers_, s_.touch(); }
    ~Viewer() { --s_.viewers_, s_.touch(); }
    Viewer(const Viewer&) = delete;
    Viewer& operator=(const Viewer&) = delete;
   private:
    LiveSession& s_;
  };
  int viewers() const { return viewers_; }

  // Wall seconds since the last request or viewer; 0 while a viewer is connected.
  double idleSeconds() const;
  void touch();

  // Clips: "last" takes the frames of the last `seconds` (at most historySeconds) at once;
  // "next" records the next seconds' frames, drawing every tick meanwhile. Returns the clip's
  // id. Throws std::invalid_argument (no ffmpeg, no frames yet, too many clips at once).
  int record(const std::string& mode, double seconds);
  std::optional<ClipInfo> clip(int id) const;
  std::vector<ClipInfo> clips() const;

 private:
  struct Clip {
    ClipInfo info;
    std::vector<std::shared_ptr<const std::string>> jpegs;
    int wanted = 0;
    std::thread encoder;
  };
  struct Stored {
    double wall;
    std::shared_ptr<const std::string> jpeg;
  };

  template <class F>
  auto apply(F&& f, bool restart) {
    std::lock_guard<std::mutex> lk(m_);
    dirty_ = true;
    struct Sync {  // the look goes to the session however f returns (picking reads its camera)
      LiveSession& s;
      bool restart;
      int exceptions = std::uncaught_exceptions();
      ~Sync() {
        s.session_.setLook(s.look_);
        if (restart && std::uncaught_exceptions() == exceptions) s.restarted();
        s.republish();
      }
    } sync{*this, restart};
    return f(session_, look_);
  }
  void restarted();  // under m_
  // Under m_: the stats of the simulation as it is now, published at once (a request's answer
  // and the next stats agree), with the rates of the last tick.
  void republish();
  void run();
  void tick(GlRenderer* renderer, double now);
  // At the end of a rate window: the size to draw at from the window's draw time (adaptSize).
  void adaptSize(int framesDrawn, double drawMs);
  void advance(double now, double wallDt);
  void collectStats(LiveStats& s);  // under m_
  void publish(std::shared_ptr<const std::string> jpeg, std::shared_ptr<Image> image, const LiveStats& s,
               double simTime, double now);
  // The encoder's thread: the JPEG of the frame drawn last while the session thread steps and
  // draws the next one (the two halves of a frame cost about the same at 1280x720).
  void encodeLoop();
  std::shared_ptr<Image> spareImage();
  void startEncoding(Clip& c);  // under clipM_

  LiveConfig config_;
  mutable std::mutex m_;  // the simulation: session_, look_, play state
  RenderSession session_;
  Look look_;
  bool playing_ = false, dirty_ = true;
  double speed_ = 1, goal_ = 0;  // goal_: simulated time the pacing aims at
  std::optional<double> seekTo_;
  bool reportedDivergence_ = false;
  std::string status_;

  // The thread's own, read by nobody else.
  double lastTick_ = 0, lastSimTime_ = 0;
  double windowStart_ = 0, windowSim_ = 0, windowPhysics_ = 0, windowDraw_ = 0;
  int windowFrames_ = 0, windowTicks_ = 0;
  double rateFps_ = 0, ratePhysics_ = 0, rateDraw_ = 0, rateAchieved_ = 0;
  bool behindTick_ = false, windowBehind_ = false, rateBehind_ = false;
  std::vector<long long> prevSteps_;   // per panel, at the last stats: steps and their cost
  std::vector<double> prevPhysics_, lastStepMs_;
  int sizeStep_ = 0;                  // index into the sizes drawn at (0: the config's)
  int slowWindows_ = 0, fastWindows_ = 0;
  std::string sizeNote_;

  // Between the session thread and the encoder.
  struct Drawn {
    std::shared_ptr<Image> image;
    LiveStats stats;
    double simTime = 0, wall = 0;
  };
  std::mutex encM_;
  std::condition_variable encCv_;
  std::optional<Drawn> drawn_;                 // drawn, not yet taken by the encoder
  std::vector<std::shared_ptr<Image>> spare_;  // frames to draw into (their pixels reused)
  std::atomic<double> encodeMs_{0};
  std::thread encoder_;

  mutable std::mutex frameM_;  // what is published
  mutable std::condition_variable frameCv_;
  LiveFrame latest_;
  std::shared_ptr<Image> front_;
  LiveStats stats_;
  long long framesDrawn_ = 0;
  std::deque<Stored> history_;
  bool imageWanted_ = false;

  mutable std::mutex clipM_;
  std::map<int, std::unique_ptr<Clip>> clips_;
  int nextClip_ = 1;
  std::atomic<int> recording_{0};  // "next" clips collecting frames

  std::atomic<int> viewers_{0};
  std::atomic<double> lastTouch_;
  std::atomic<bool> stop_{false}, closed_{false};
  std::mutex stopM_;
  std::condition_variable stopCv_;
  std::thread thread_;
};

}  // namespace substep::render

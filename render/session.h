// The render session: what every front end of the renderer shares (`substep render`, `substep
// snapshot`, the snapshot tests, substep-render-bench, and the server to come). It holds a scene's
// panels (one World per solver setting, side by side when there are two to four), steps them to a
// time, and turns their states into draw lists, with the HUD and labels, and into frames. Where
// frames go is a FrameSink's business (render/frame_sink.h).
//
//   RenderSession s(scene, {{settings, ""}}, look);
//   s.advanceTo(1.0);
//   if (const Panel* p = s.firstDiverged()) ...   // p->problem(); the other panels went on
//   s.frame(renderer, image);
//
// A session reads physics and steps it; it never changes how physics works. The renderer is the
// caller's: a context costs more than a frame, so one renderer can draw many sessions (tests), and
// one session can be drawn by several renderers (the benchmark's variants).
#pragma once

#include "physics/run.h"
#include "physics/scene_file.h"
#include "physics/settings.h"
#include "physics/snapshot.h"
#include "physics/world.h"
#include "render/gl_renderer.h"
#include "render/image.h"
#include "render/scene_builder.h"

#include <deque>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace substep::render {

// One panel's simulation: the solver settings, and a name for labels and messages (the
// `--compare` text, e.g. "a5:n=4"; empty for a lone panel).
struct PanelSetup {
  SolverSettings settings;
  std::string name;
};

// What frames show besides the states; may change between frames.
struct Look {
  ViewOptions view;
  CameraPreset camera;     // chooseCamera(scene, options): placed at each panel's state
  double orbit = 0;        // camera turn [degrees per simulated second]
  bool stepCost = false;   // HUD shows each panel's measured step cost: wall-clock, so frames differ between runs
};

// A World could not be made with a panel's settings.
class PanelError : public std::invalid_argument {
 public:
  PanelError(int panel, const std::string& message) : std::invalid_argument(message), panel(panel) {}
  const int panel;  // index into the setups
};

// How much of their past a session's panels keep (the timeline): the steps of the last `seconds`
// of simulated time, and at most `bytes` of snapshots in all (shared equally by the panels); the
// older go first.
struct HistoryLimits {
  double seconds = 60;
  size_t bytes = size_t{512} << 20;
};

// A panel: its World, what its steps cost, whether it diverged, and its past. A panel keeps a
// Snapshot of every step (its history, from t = 0 while the limits allow) and shows one of them:
// the newest (live) or the one a cursor points at (the timeline scrubbed back). A recorded panel
// (a recording's frames, physics/recording.h) has its whole history from the start and never
// steps its World: it ends where the recording does.
class Panel {
 public:
  Panel(const Scene& scene, PanelSetup setup);  // throws std::invalid_argument (bad settings)
  // A recorded panel: `frames` in order of time, at least one.
  Panel(const Scene& scene, PanelSetup setup, std::vector<Snapshot> frames);

  const PanelSetup& setup() const { return setup_; }
  const std::string& name() const { return setup_.name; }
  const SolverSettings& settings() const { return world_->settings(); }
  const World& world() const { return *world_; }
  // What is shown: the snapshot at the cursor, else the newest kept (after a divergence, the last
  // finite step). state() is its state.
  const Snapshot& shown() const { return cursor_ ? history_[*cursor_] : history_.back(); }
  const State& state() const { return shown().state; }
  bool live() const { return !cursor_; }
  bool recorded() const { return recorded_; }
  // Nothing more to show going forward: diverged, or a recording at its last frame.
  bool ended() const { return diverged_ || (recorded_ && live()); }
  const std::deque<Snapshot>& history() const { return history_; }
  int cursor() const { return cursor_ ? static_cast<int>(*cursor_) : static_cast<int>(history_.size()) - 1; }
  bool diverged() const { return diverged_; }
  // Its algorithm refused the scene (A1 beyond its size): it stopped, as a diverged panel does,
  // but the settings are at fault, not the run.
  bool refused() const { return refused_; }
  // After a divergence: `panel "a5:n=4": the simulation diverged at step 12 (t = 0.2 s): body ...`
  // (without the panel part when it has no name).
  const std::string& problem() const { return problem_; }
  double divergedAt() const { return divergedAt_; }  // the time of the step that diverged [s]
  double lastStepMs() const { return lastStepMs_; }  // mean cost of the steps of the last advance that took any [ms]
  long long steps() const { return steps_; }          // taken since the start
  double physicsSeconds() const { return physicsSeconds_; }  // their cost [s]

 private:
  friend class RenderSession;
  void advanceTo(double t);
  void stepOnce();
  bool takeStep();  // false when it diverged
  void keep(Snapshot s);
  void setLimits(const HistoryLimits& limits);  // and drops what they no longer keep
  void trim();                                  // the oldest, while the history exceeds the limits
  // The cursor to the newest kept snapshot at or before t (the first when t is earlier); live
  // when that is the newest.
  void view(double t);
  void moveCursor(long long by);  // kept snapshots forward (> 0) or back

  PanelSetup setup_;
  std::unique_ptr<World> world_;
  std::unique_ptr<WorldEngine> engine_;
  std::unique_ptr<RunDriver> run_;  // the run driver's one step, its one divergence message
  std::deque<Snapshot> history_;
  std::optional<size_t> cursor_;
  size_t historyBytes_ = 0;
  HistoryLimits limits_;
  std::function<void(const Snapshot&)> onKeep_;
  bool recorded_ = false;
  bool diverged_ = false, refused_ = false;
  std::string problem_;
  double divergedAt_ = std::numeric_limits<double>::quiet_NaN();
  double lastStepMs_ = std::numeric_limits<double>::quiet_NaN();
  double costSum_ = 0;  // [s] of the steps of this advance
  int costSteps_ = 0;
  long long steps_ = 0;
  double physicsSeconds_ = 0;
};

// The bytes a snapshot holds (for HistoryLimits).
size_t snapshotBytes(const Snapshot& s);

class RenderSession {
 public:
  // Worlds keep a reference to the scene's model, hence shared. Throws PanelError when a
  // setting cannot make a World.
  RenderSession(std::shared_ptr<const Scene> scene, const std::vector<PanelSetup>& panels, Look look = {});

  const Scene& scene() const { return *scene_; }
  int panelCount() const { return static_cast<int>(panels_.size()); }
  const Panel& panel(int i) const { return *panels_[static_cast<size_t>(i)]; }
  const Panel* firstDiverged() const;  // nullptr while every panel is finite

  // Goes forward to the step nearest t: through the kept history while the panels show the past
  // (the same trajectory, not stepped again), then by stepping every panel that has not ended. A
  // panel that diverges stops, marked; the others go on.
  void advanceTo(double t);
  void step();   // one step forward of every panel that has not ended (a kept one when in the past)
  // The timeline: every panel shows its newest kept step at or before t (the first kept when t is
  // earlier; live at the newest); by(k): k kept steps of panel 0 forward or back, the others to
  // its time; live(): the newest of each.
  void view(double t);
  void viewBy(long long k);
  void viewLive();
  bool live() const;              // every panel shows its newest step
  bool ended() const;             // every panel has ended (nothing to step or replay forward)
  double time() const { return panel(0).state().time; }  // shown [s]
  double firstKept() const;       // the earliest time every panel still keeps [s]
  double lastKept() const;        // panel 0's newest [s]
  // What history the panels keep; applies to the kept past at once.
  void setHistoryLimits(const HistoryLimits& limits);
  const HistoryLimits& historyLimits() const { return limits_; }
  // Called with each snapshot a panel keeps (each step; a recorded panel's frames when made, and a
  // new panel's first at t = 0), with the scene the panel runs.
  using SnapshotHook = std::function<void(int panel, const std::shared_ptr<const Scene>& scene, const Snapshot&)>;
  void setSnapshotHook(SnapshotHook hook);
  void reset();  // every panel back to the scene's initial state, same settings
  // Replace every panel, or one, starting from the scene's initial state. Throw PanelError.
  void setPanels(const std::vector<PanelSetup>& panels);
  void setPanel(int i, const PanelSetup& setup);
  // Another scene, with its panels, from its initial state. Throws PanelError (nothing changed).
  void setScene(std::shared_ptr<const Scene> scene, const std::vector<PanelSetup>& panels);
  // Changes a panel's solver between steps; it goes on from its state (World::setSettings).
  // Throws std::invalid_argument while the timeline shows the past (the past cannot change).
  void setSettings(int i, const SolverSettings& settings);
  // A recorded session: one panel per recording's panel (`frames`, per panel), from its start.
  // Throws PanelError.
  void setRecorded(std::shared_ptr<const Scene> scene, const std::vector<PanelSetup>& panels,
                   std::vector<std::vector<Snapshot>> frames);
  bool recorded() const { return !panels_.empty() && panels_[0]->recorded(); }

  const Look& look() const { return look_; }
  void setLook(const Look& look) { look_ = look; }
  void setCamera(const CameraPreset& camera, double orbit = 0) {
    look_.camera = camera;
    look_.orbit = orbit;
  }

  // What pixel (x, y) of a frame of width x height (the grid of gridLayout()) shows: the panel
  // under it and the nearest dynamic body along its ray. panel -1: between panels; hit.body -1:
  // no body.
  struct Pick {
    int panel = -1;
    Vec3 origin = Vec3::Zero(), direction = Vec3::UnitZ();  // the ray, unit direction [m]
    RayHit hit;
  };
  Pick pick(int width, int height, double x, double y) const;
  // An impulse [N s] at `point` on `body` as panel `from` has it, applied to every panel that has
  // not diverged at the same point of the body's frame, so that panels stay comparable. Throws
  // std::invalid_argument for a static body or a non-finite impulse, while the timeline shows the
  // past, or for a recording.
  void push(int from, int body, const Vec3& impulse, const Vec3& point);

  // Panel i's draw list: its camera, the HUD (a lone panel: scene, settings, time; one of a grid:
  // time, with its settings as the label); drawn at `state` instead of the panel's when given.
  DrawList drawList(int i, const State* state = nullptr) const;
  std::vector<DrawList> drawLists() const;
  // Every panel, in a grid when more than one, at the renderer's size.
  void frame(GlRenderer& renderer, Image& out) const;
  Image frame(GlRenderer& renderer) const;

 private:
  void hookPanel(int i);  // the snapshot hook and the history limits into panel i
  // A panel's share of the limits: the bytes split equally.
  HistoryLimits panelLimits() const { return {limits_.seconds, limits_.bytes / panels_.size()}; }
  std::shared_ptr<const Scene> scene_;
  std::vector<std::unique_ptr<Panel>> panels_;
  Look look_;
  HistoryLimits limits_{0, size_t{1} << 30};  // the newest only, unless asked (a video needs no past)
  SnapshotHook hook_;
};

// The views of a frame: one list filling it, or the gridLayout() panels.
std::vector<View> gridViews(const std::vector<DrawList>& lists, int width, int height);

}  // namespace substep::render

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

#include "physics/scene_file.h"
#include "physics/settings.h"
#include "physics/run.h"
#include "physics/world.h"
#include "render/gl_renderer.h"
#include "render/image.h"
#include "render/scene_builder.h"

#include <limits>
#include <memory>
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

// A panel: its World, what its steps cost, and whether it diverged.
class Panel {
 public:
  Panel(const Scene& scene, PanelSetup setup);  // throws std::invalid_argument (bad settings)

  const PanelSetup& setup() const { return setup_; }
  const std::string& name() const { return setup_.name; }
  const SolverSettings& settings() const { return world_->settings(); }
  const World& world() const { return *world_; }
  // The state drawn: the world's, or after a divergence the last state the panel advanced from.
  const State& state() const { return diverged_ ? lastGood_ : world_->state(); }
  bool diverged() const { return diverged_; }
  // Its algorithm refused the scene (A1 beyond its size): it stopped, as a diverged panel does,
  // but the settings are at fault, not the run.
  bool refused() const { return refused_; }
  // After a divergence: `panel "a5:n=4": the simulation diverged at step 12 (t = 0.2 s): body ...`
  // (without the panel part when it has no name).
  const std::string& problem() const { return problem_; }
  double lastStepMs() const { return lastStepMs_; }  // mean cost of the steps of the last advance that took any [ms]
  long long steps() const { return steps_; }          // taken since the start
  double physicsSeconds() const { return physicsSeconds_; }  // their cost [s]

 private:
  friend class RenderSession;
  void advanceTo(double t);
  void stepOnce();
  bool takeStep();  // false when it diverged

  PanelSetup setup_;
  std::unique_ptr<World> world_;
  std::unique_ptr<WorldEngine> engine_;
  std::unique_ptr<RunDriver> run_;  // the run driver's one step, its one divergence message
  State lastGood_;
  bool diverged_ = false, refused_ = false;
  std::string problem_;
  double lastStepMs_ = std::numeric_limits<double>::quiet_NaN();
  double costSum_ = 0;  // [s] of the steps of this advance
  int costSteps_ = 0;
  long long steps_ = 0;
  double physicsSeconds_ = 0;
};

class RenderSession {
 public:
  // Worlds keep a reference to the scene's model, hence shared. Throws PanelError when a
  // setting cannot make a World.
  RenderSession(std::shared_ptr<const Scene> scene, const std::vector<PanelSetup>& panels, Look look = {});

  const Scene& scene() const { return *scene_; }
  int panelCount() const { return static_cast<int>(panels_.size()); }
  const Panel& panel(int i) const { return *panels_[static_cast<size_t>(i)]; }
  const Panel* firstDiverged() const;  // nullptr while every panel is finite

  // Steps every panel that has not diverged until its time is the step nearest t. Panels only go
  // forward: to seek back, reset() then advanceTo(). A panel that diverges stops, marked; the
  // others go on.
  void advanceTo(double t);
  void step();   // one step of every panel that has not diverged
  void reset();  // every panel back to the scene's initial state, same settings
  // Replace every panel, or one, starting from the scene's initial state. Throw PanelError.
  void setPanels(const std::vector<PanelSetup>& panels);
  void setPanel(int i, const PanelSetup& setup);
  // Another scene, with its panels, from its initial state. Throws PanelError (nothing changed).
  void setScene(std::shared_ptr<const Scene> scene, const std::vector<PanelSetup>& panels);
  // Changes a panel's solver between steps; it goes on from its state (World::setSettings).
  void setSettings(int i, const SolverSettings& settings);

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
  // std::invalid_argument for a static body or a non-finite impulse.
  void push(int from, int body, const Vec3& impulse, const Vec3& point);

  // Panel i's draw list: its camera, the HUD (a lone panel: scene, settings, time; one of a grid:
  // time, with its settings as the label); drawn at `state` instead of the panel's when given.
  DrawList drawList(int i, const State* state = nullptr) const;
  std::vector<DrawList> drawLists() const;
  // Every panel, in a grid when more than one, at the renderer's size.
  void frame(GlRenderer& renderer, Image& out) const;
  Image frame(GlRenderer& renderer) const;

 private:
  std::shared_ptr<const Scene> scene_;
  std::vector<std::unique_ptr<Panel>> panels_;
  Look look_;
};

// The views of a frame: one list filling it, or the gridLayout() panels.
std::vector<View> gridViews(const std::vector<DrawList>& lists, int width, int height);

}  // namespace substep::render

// What the calls of `substep serve` ask for, read from their bodies and checked (HttpError 400
// naming the field) before anything changes: method specs and panels, a settings object, a
// camera or view change, a pixel of the frame. The handlers (handlers.h) then only act.
#pragma once

#include "app/server/http.h"
#include "app/server/sessions.h"
#include "render/scene_builder.h"

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace substep::app::web {

// What one request may ask for.
constexpr int kMaxPanels = 4;
constexpr int kMaxWidth = 1920, kMaxHeight = 1080, kMinSide = 64;
constexpr double kMaxSeek = 3600;    // [s] simulated
constexpr int kMaxSteps = 600;       // one request's single steps

// One method spec ("a5:n=4:kappa=0.85") as overrides.
SolverOverrides methodOverrides(const std::string& text, const std::string& field);
// "a2:m=4,a5:n=4" or ["a2:m=4", "a5:n=4"]: 1 to 4 panels.
std::vector<WebSession::PanelState> panelsOf(const json& v, const std::string& field);
// The panels of a new session: "method" (one) or "methods", else one with the scene's settings.
std::vector<WebSession::PanelState> newPanels(const Fields& f);
// "panel": the one panel of `count` a change is for, else all of them.
std::vector<int> panelTargets(const Fields& f, int count);
// "scene": a scene's name (required).
std::string sceneName(const Fields& f);
// The panels' settings over the scene's, each resolved (and so checked) as the command line is.
// Each panel's settings: the scene's under the panel's. With sleepByDefault (serve's default,
// `--no-sleep` turns it off) islands at rest sleep unless the scene or the panel says otherwise.
std::vector<PanelSetup> setups(const Scene& scene, const std::vector<WebSession::PanelState>& panels, bool sleepByDefault);
// A settings object ({"n": 8, "warm": false, "kappa": null}) applied to `u` through the settings
// table; a new algorithm starts from its own defaults.
void changeSettings(SolverOverrides& u, const json& settings);
// "size" of a new session: WIDTHxHEIGHT within the limits.
void frameSize(const Fields& f, int& width, int& height);
// "x", "y": a pixel of a frame of `width` x `height`.
std::pair<double, double> pixel(const Fields& f, int width, int height);

// A camera change of POST .../camera: every value read and checked before the camera changes.
struct CameraChange {
  static const std::vector<std::string> kFields;
  explicit CameraChange(const Fields& f);
  // Checks the names against the scene: HttpError 400 for a body it has not.
  void checkFollow(const Scene& scene, const std::string& sceneName) const;
  // Applies it to the look, `chosen` being the preset it names; `state` is panel 0's, where the
  // camera is placed for panning, `height` the frame's.
  void apply(render::Look& look, const std::optional<CameraPreset>& chosen, const Model& model, const State& state,
             int height) const;

  std::optional<std::string> preset, follow;
  std::optional<double> yaw, pitch, distance, fov, orbit, zoom;
  std::optional<Vec3> target;
  std::optional<std::pair<double, double>> rotate, pan;
};

// A view change of POST .../view.
struct ViewChange {
  static const std::vector<std::string> kFields;
  explicit ViewChange(const Fields& f);
  // Reads "highlight", which names bodies of the scene.
  void readHighlight(const Fields& f, const Scene& scene, const std::string& sceneName);
  void apply(render::Look& look) const;

  std::optional<render::ColourMode> colour;
  std::optional<double> speedScale, errorScale, forceScale;
  std::optional<bool> contacts, joints, hud, forces, jointErrors;
  std::optional<std::vector<std::string>> highlight;
};

}  // namespace substep::app::web

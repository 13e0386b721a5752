// The scene builder: a physics state (Model, State, the world's manifolds) to a DrawList. It reads
// physics and never steps it.
#pragma once

#include "physics/collision/manifold.h"
#include "physics/model.h"
#include "physics/scene_file.h"
#include "physics/settings.h"
#include "physics/state.h"
#include "render/draw_list.h"

#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace substep::render {

// How bodies are coloured, so a viewer can tell them apart or read a quantity off them.
enum class ColourMode {
  Auto,      // by group when the scene has two or more (ragdolls, chains), else by body
  Body,      // a distinct colour per body
  Group,     // one colour per Body::group (bodies without a group: per body)
  Speed,     // |v|: blue (0) to red (ViewOptions::speedScale and above)
  Activity,  // resting (|v| and |ω| below ViewOptions::restSpeed) grey-blue, moving orange
  Error,     // the body's worst contact penetration or joint separation: green (0) to red (errorScale)
};
std::optional<ColourMode> parseColourMode(const std::string& s);  // "auto", "body", "group", "speed", "activity" ("sleep"), "error"
const char* colourModeName(ColourMode m);

struct ViewOptions {
  ColourMode colour = ColourMode::Auto;
  bool contacts = false;       // contact points and normals
  bool joints = false;         // joint anchors, arms and axes
  bool hud = true;             // text: scene, settings, time, step cost
  std::vector<std::string> highlight;  // body names drawn with a glow
  double speedScale = 5;       // [m/s] red in Speed mode
  double restSpeed = 0.05;     // [m/s and rad/s] Activity mode: below both, a body is at rest
  double errorScale = 0.01;    // [m] red in Error mode
};

// What the heads-up text says besides the scene.
struct HudInfo {
  std::string scene;          // first line, e.g. "pyramid: 210 bodies, 0 joints"
  std::string settings;       // e.g. "a5 Havok actual  n=4 m=1 κ=1 τ=0.6"
  double time = 0;            // simulated [s]
  double stepMs = std::numeric_limits<double>::quiet_NaN();  // mean cost of the frame's steps [ms]; NaN: not shown
  std::string status;         // e.g. "diverged at t = 2.1 s", shown in red
};

std::string sceneLine(const Scene& scene);

// Camera placement: a preset from the scene file plus command-line changes.
struct CameraOptions {
  std::string preset;                   // scene camera name; empty: the scene's first, or fitted
  std::optional<double> yaw, pitch, distance, fov;  // degrees, metres
  std::optional<Vec3> target;
  std::optional<std::string> follow;    // body name; "" turns a preset's follow off
  double orbit = 0;                     // degrees of yaw per simulated second
};

// The preset to use: the named one, else the scene's first, else one fitted to the bodies, with
// the options applied. Throws std::invalid_argument naming the unknown camera or body.
CameraPreset chooseCamera(const Scene& scene, const CameraOptions& o);
// A camera that frames every non-plane body of the state, looking from yaw 30°, pitch 20°.
CameraPreset fittedCamera(const Model& model, const State& state);
// The look-at camera of a preset at a state: follows its body, turns by `orbit` deg/s.
Camera placeCamera(const CameraPreset& preset, const Model& model, const State& state, double orbit = 0);

// Worst penetration of each body's contacts and separation of its joints, at the state [m].
std::vector<double> bodyErrors(const Model& model, const State& state, const std::vector<Manifold>* manifolds);

DrawList buildDrawList(const Model& model, const State& state, const std::vector<Manifold>* manifolds,
                       const Camera& camera, const ViewOptions& view, const HudInfo& hud);

// Colours, exposed for tests and legends.
Vec3f bodyColour(int index);          // distinct hues (golden-ratio steps)
Vec3f groupColour(int group, int member);  // the group's hue, members in different shades
Vec3f rampColour(double t);           // t in [0,1]: blue, cyan, green, yellow, red
Vec3f staticColour();

}  // namespace substep::render

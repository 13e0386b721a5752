// The scene builder: a Snapshot of a step (bodies, contacts, joints; physics/snapshot.h) to a
// DrawList. It reads physics and never steps it, so a recording draws exactly as a live run.
#pragma once

#include "physics/model.h"
#include "physics/scene_file.h"
#include "physics/settings.h"
#include "physics/snapshot.h"
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
  Activity,  // resting (|v| and |ω| below ViewOptions::restSpeed) grey-blue, moving orange,
             // asleep (Snapshot::asleep, SolverSettings::sleep) dark blue
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
  bool forces = false;         // contact impulses: λn along each normal, friction at each manifold's centre
  bool jointErrors = false;    // each joint's separation: a red segment from A's anchor to B's
  double forceScale = 0;       // arrow length per impulse [m per N s]; 0: autoForceScale
  double impulseTime = 0;      // [s] what one drawn impulse acts over (impulseTime of the settings); 0: a step
};

// The time a snapshot's impulses act over: the last sub-step's, h / n, for methods with
// sub-steps, else the step h [s].
double impulseTime(const SolverSettings& settings);

// The scale of the force arrows when ViewOptions::forceScale is 0: the impulse that holds the
// heaviest dynamic body up for the impulses' time τ, m |g| τ, drawn as long as that body's
// bounding radius, rounded down to 1, 2 or 5 times a power of ten [m per N s]. It depends on the
// model and the settings only, so a run's arrows keep one scale from frame to frame. τ is
// ViewOptions::impulseTime, else the snapshot's step (its time over its step count; 1/60 s
// before the first step).
double autoForceScale(const Model& model, const Snapshot& snapshot, double impulseTime = 0);
// What a force arrow's length means, for the legend: a length of 1, 2 or 5 times a power of ten
// at most `about` [m] and the impulse it stands for at `scale`, e.g. "arrow 10 cm = 2.5 N s".
std::string forceLegend(double scale, double about);

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

// Worst penetration of each body's contacts and separation of its joints in the snapshot [m].
std::vector<double> bodyErrors(const Model& model, const Snapshot& snapshot);

DrawList buildDrawList(const Model& model, const Snapshot& snapshot, const Camera& camera, const ViewOptions& view,
                       const HudInfo& hud);

// Colours, exposed for tests and legends.
Vec3f bodyColour(int index);          // distinct hues (golden-ratio steps)
Vec3f groupColour(int group, int member);  // the group's hue, members in different shades
Vec3f rampColour(double t);           // t in [0,1]: blue, cyan, green, yellow, red
Vec3f staticColour();
Vec3f normalImpulseColour();          // force arrows along contact normals
Vec3f frictionImpulseColour();        // friction arrows
Vec3f jointErrorColour();             // joint error segments

}  // namespace substep::render

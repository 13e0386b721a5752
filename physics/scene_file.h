// Scene files: JSON in assets/scenes/. The only I/O the physics library does.
// Every error names the file, the JSON path of the offending value and what was expected,
// e.g. "assets/scenes/x.json: bodies[3].shape.radius: expected a number > 0, got -1".
#pragma once

#include "physics/limits.h"
#include "physics/model.h"
#include "physics/settings.h"
#include "physics/state.h"

#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace substep {

class SceneError : public std::runtime_error {
 public:
  SceneError(const std::string& file, const std::string& path, const std::string& message);
  const std::string file, path, message;
};

// Where a viewer looks from; read by the renderer (render/), ignored by physics.
struct CameraPreset {
  std::string name;            // "default" for the first
  Vec3 target = Vec3::Zero();  // look-at point [m]
  double yaw = 30;             // degrees about +Y, 0 looks along -Z
  double pitch = 20;           // degrees above the horizon
  double distance = 10;        // [m]
  double fovY = 45;            // vertical field of view, degrees
  std::string follow;          // name of a body to keep at the centre, empty for none
};

// What a scene states about how a run of it is judged: the lab's atlas, sweeps and advice read it
// (lab/). Physics only parses and checks it. Quantities a criterion bounds, by name (all "at
// most", SI units; lab/metrics.h measures each):
//   penetration, penetration_end [m]   deepest contact point over the run / at its end
//   joint_error [m]                    largest anchor separation of any joint
//   joint_angle_error [rad]            hinge axes apart, a fixed joint's turn
//   limit_excess [rad]                 largest angle beyond a hinge, swing or twist limit
//   displacement [m]                   largest distance from the start of a resting body (all
//                                      dynamic bodies when no "rest" list is given)
//   sideways [m]                       ... of that distance, the largest across gravity (a
//                                      stack's settling under its weight left out)
//   jitter [m/s]                       largest speed of a resting body in the run's second half
//   speed [m/s]                        largest speed of any body (ejection speed)
//   energy_drift, momentum_drift       largest relative change (conservative / free scenes)
//   trajectory_error [m]               against the reference
//   reference_error                    relative error of the reference's closed-form quantity
const std::vector<std::string>& criterionMetrics();

// A reference the lab measures a run against.
struct SceneReference {
  enum class Kind {
    Pendulum,    // closed form: the period of a body swinging about a fixed pivot (elliptic integral)
    FreeFall,    // closed form: x0 + v0 t + g t^2 / 2 for every dynamic body
    TorqueFree,  // closed form: each body's world angular momentum and energy stay constant
    Converged,   // a run of `method` at a small h, checked by halving h
  };
  Kind kind = Kind::Converged;
  std::string body;           // Pendulum: the swinging body
  Vec3 pivot = Vec3::Zero();  // Pendulum: the fixed point it swings about [m]
  std::string method;         // Converged: a method spec with its h, e.g. "a1:h=1/960"
  double change = 0.01;       // Converged: halving h may move the answer by at most this share of the motion
};
const char* referenceKindName(SceneReference::Kind k);  // "pendulum", ...

struct SceneCriteria {
  std::string stresses;                 // what the scene stresses, one line
  double seconds = 3;                   // how long a lab run lasts [s]
  std::optional<double> tolerance;      // a resting body that moved further has "moved" (collapse time) [m]
  std::vector<int> rest;                // bodies that should rest (jitter, displacement); empty: every dynamic body
  bool conservative = false;            // no energy enters or leaves: energy drift is measured
  std::string error;                    // the quantity charts and advice call "error" (criterionMetrics())
  std::optional<SceneReference> reference;
  SolverOverrides with;                 // settings every method runs this scene with (e.g. the gyroscopic term)
  std::vector<std::pair<std::string, double>> pass;  // quantity -> at most; all must hold (and the run stay finite)
  struct Moving {                        // these bodies must move at least `atLeast` (a box that should slide)
    std::vector<int> bodies;
    double atLeast = 0;
  };
  std::optional<Moving> moving;
  struct StayIn {                        // a body that must stay inside a box (a projectile before a wall)
    int body = -1;
    Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
  };
  std::optional<StayIn> stayIn;
  struct Turns {                         // a body's local axis must turn at least this far (a flip)
    int body = -1;
    Vec3 axis = Vec3::UnitY();           // in the body's frame at the start (unit)
    double atLeast = 0;                  // [rad]
  };
  std::optional<Turns> turns;
};

struct Scene {
  std::string file;            // as given to loadScene
  std::string hash;            // of the file's content (contentHash, physics/state_hash.h): records name it
  std::string text;            // the content parsed, so that a recording can carry its scene (physics/recording.h)
  std::string baseDir;         // where its mesh paths are resolved from
  std::string description;
  Model model;
  State initial;
  SolverOverrides solver;      // the file's "solver" block, all fields optional
  std::vector<CameraPreset> cameras;
  std::optional<SceneCriteria> criteria;  // the file's "criteria" block
};

// What a scene may hold in total (the numbers in it are checked against physics/limits.h).
struct SceneLimits {
  long long maxBodies = limits::kDefaultMaxBodies;  // bodies, and joints, of the whole scene
};

// Reads and validates a scene file: a regular file of at most limits::kMaxSceneBytes, every
// number within its range (limits.h). Throws SceneError.
Scene loadScene(const std::string& path, const SceneLimits& lim = {});
// Same from text; `file` is used in messages, `baseDir` to resolve mesh paths.
Scene parseScene(const std::string& text, const std::string& file, const std::string& baseDir,
                 const SceneLimits& lim = {});

// Why `path` cannot be read as an input file, or "" if it can: it must be a regular file (not a
// FIFO, device or folder: those block or never end) of at most maxBytes, with no NUL in its
// name. With `contents`, reads it too. Used for scenes and meshes.
std::string checkInputFile(const std::string& path, size_t maxBytes, std::string* contents = nullptr);
// The contents of an input file; throws SceneError(path, "", why).
std::string readInputFile(const std::string& path, size_t maxBytes);

}  // namespace substep

// Scene files: JSON in assets/scenes/. The only I/O the physics library does.
// Every error names the file, the JSON path of the offending value and what was expected,
// e.g. "assets/scenes/x.json: bodies[3].shape.radius: expected a number > 0, got -1".
#pragma once

#include "physics/limits.h"
#include "physics/model.h"
#include "physics/settings.h"
#include "physics/state.h"

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

struct Scene {
  std::string file;            // as given to loadScene
  std::string description;
  Model model;
  State initial;
  SolverOverrides solver;      // the file's "solver" block, all fields optional
  std::vector<CameraPreset> cameras;
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

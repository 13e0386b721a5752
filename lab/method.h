// A method the lab runs a scene with: one of substep's algorithms with its settings, or the
// Bullet peer, written in the spec language of `--compare` (physics/settings.h), value lists and
// all: "a5:n=1|2|4|8:m=1" is four methods, "bullet:it=10" one.
#pragma once

#include "physics/scene_file.h"
#include "physics/settings.h"

#include <optional>
#include <string>
#include <vector>

namespace substep::lab {

struct Method {
  std::string text;           // one combination, as written: "a5:n=4:m=1", "bullet:it=10"
  SolverOverrides overrides;  // what it names
  std::string peer;           // "" for substep's algorithms, "bullet"

  bool isBullet() const { return peer == kBulletPeer; }
  // The series a chart draws it in: its algorithm ("a5") or peer ("bullet").
  std::string family() const;
};

// A comma-separated list of specs, each expanded. Throws std::invalid_argument naming the spec.
std::vector<Method> parseMethods(const std::string& list);

// How a method runs a scene: the method's settings, over the scene's criteria "with" (settings a
// scene needs, e.g. the gyroscopic term), over `dt` (a sweep's) or else the scene's time step.
// The rest of a scene's solver block is not used, so that a method means the same on every
// scene (as in substep-bench). For the Bullet peer the same rules give its h, iterations (10 by
// default) and gyroscopic term (Bullet's own default: implicit). Throws std::invalid_argument.
SolverSettings methodSettings(const Method& m, const Scene& scene, std::optional<double> dt = std::nullopt);

// The Bullet peer's settings, read from methodSettings()' result.
struct BulletSettings {
  double dt = 1.0 / 60;
  int iterations = 10;
  bool gyroscopic = true;
};
BulletSettings bulletSettings(const Method& m, const Scene& scene, std::optional<double> dt = std::nullopt);

}  // namespace substep::lab

// A method the lab runs a scene with: one of substep's algorithms with its settings, or a peer
// engine (Bullet, ODE, MuJoCo: lab/peers.h), written in the spec language of `--compare`
// (physics/settings.h), value lists and all: "a5:n=1|2|4|8:m=1" is four methods, "ode:it=20" one.
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
  std::string peer;           // "" for substep's algorithms, else the peer's name: "bullet", "ode", "mujoco"
  PeerOptions peerOptions;    // a peer's own keys, as the spec gives them (not resolved)

  bool isPeer() const { return !peer.empty(); }
  bool isBullet() const { return peer == kBulletPeer; }
  // The series a chart draws it in: its algorithm ("a5") or peer ("bullet").
  std::string family() const;
};

// A comma-separated list of specs, each expanded. Throws std::invalid_argument naming the spec.
std::vector<Method> parseMethods(const std::string& list);

// How a method runs a scene: the method's settings, over the scene's criteria "with" (settings a
// scene needs, e.g. the gyroscopic term), over `dt` (a sweep's) or else the scene's time step.
// The rest of a scene's solver block is not used, so that a method means the same on every
// scene (as in substep-bench). For a peer the same rules give its h, iterations (its own default:
// Bullet 10, ODE 20, MuJoCo 100) and gyroscopic term (Bullet's and ODE's own default: on, written
// implicit); its own keys are peerOptions(). Throws std::invalid_argument.
SolverSettings methodSettings(const Method& m, const Scene& scene, std::optional<double> dt = std::nullopt);

// The Bullet peer's settings, read from methodSettings()' result.
struct BulletSettings {
  double dt = 1.0 / 60;
  int iterations = 10;
  bool gyroscopic = true;
};
BulletSettings bulletSettings(const Method& m, const Scene& scene, std::optional<double> dt = std::nullopt);

// A peer's own keys, every one: the method's, else the peer's defaults (empty for substep's).
PeerOptions peerOptions(const Method& m);

}  // namespace substep::lab

// The lab's peer engines, one interface for all: Bullet (lab/bullet_peer.h), ODE (lab/ode_peer.h)
// and MuJoCo (lab/mujoco_peer.h), each stepping the same scene from the same state in this
// process, read back into substep's State after every step. A method spec names one
// (physics/settings.h: `bullet:it=10`, `ode:it=20:sor=1.3`, `mujoco:solver=newton`); this file says
// whether it can take a scene, builds its engine, and writes and reads its settings as records keep
// them (so that `substep rerun` steps it again).
#pragma once

#include "lab/method.h"
#include "physics/model.h"
#include "physics/run.h"
#include "physics/settings.h"
#include "physics/state.h"

#include <nlohmann/json.hpp>

#include <memory>
#include <string>

namespace substep::lab {

// Every setting a peer runs with, resolved.
struct PeerSettings {
  std::string peer;                      // "bullet", "ode", "mujoco"
  double dt = 1.0 / 60;
  int iterations = 10;
  Gyroscopic gyroscopic = Gyroscopic::Implicit;  // Bullet, ODE: none turns their own term off
  PeerOptions options;                   // every one of the peer's own keys

  double option(const std::string& key) const;      // throws std::logic_error for a key it lacks
  std::string optionText(const std::string& key) const;  // "quick", "1.3"
};

// The method's, resolved: `resolved` is methodSettings()' result for it.
PeerSettings peerSettings(const Method& m, const SolverSettings& resolved);

// Why the peer cannot run the scene from `initial` (empty if it can), e.g. "body \"m\" is a
// convex_mesh (...)". A run refuses such a scene with this reason, never approximates it.
std::string peerUnsupported(const std::string& peer, const Model& model, const State& initial);

// "Bullet", "ODE", "MuJoCo": the engine's own name, for messages.
std::string peerDisplayName(const std::string& peer);

// The library's version, e.g. "3.24 (float)", "0.16.2 (double)", "2.2.2".
std::string peerVersion(const std::string& peer);

// The engine the run driver steps. Throws std::invalid_argument when the scene is unsupported.
std::unique_ptr<Engine> makePeerEngine(const PeerSettings& s, const Model& model, const State& initial);

// As records and recordings keep them: {"dt", "iterations", "gyroscopic" (Bullet, ODE), the own keys}.
nlohmann::json peerSettingsJson(const PeerSettings& s);
// Back from a record; throws std::invalid_argument naming `where` and the field.
PeerSettings peerSettingsFromJson(const std::string& peer, const nlohmann::json& j, const std::string& where);

// "ode it=20 h=1/60 gyro=on sor=1.3 step=quick erp=0.2 cfm=1e-10 layer=0.001", for messages.
std::string peerLine(const PeerSettings& s);

}  // namespace substep::lab

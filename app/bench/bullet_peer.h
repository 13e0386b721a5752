// The Bullet peer of substep-bench: a scene of boxes rebuilt in Bullet 3 (btDiscreteDynamicsWorld,
// sequential impulse solver), started from the same coordinates as our World, so both engines
// step the very same initial state. Bullet's headers stay inside bullet_peer.cpp.
#pragma once

#include "physics/model.h"
#include "physics/state.h"

#include <memory>
#include <string>

namespace substep::bench {

// Why Bullet cannot build the model (empty if it can): the peer takes boxes only, no joints.
std::string bulletUnsupported(const Model& model);

// Bullet's version as it reports it, e.g. "3.24 (float)": btScalar's precision.
std::string bulletVersion();

class BulletPeer {
 public:
  // Every body of `model` at its pose in `initial`: boxes (btBoxShape with the model's half
  // extents), the model's mass, friction and restitution; static bodies have mass 0. Gravity from
  // the model. `iterations` solver iterations, Bullet's defaults otherwise; no body ever sleeps
  // (DISABLE_DEACTIVATION on every body). Throws std::invalid_argument for unsupported models.
  BulletPeer(const Model& model, const State& initial, double dt, int iterations);
  ~BulletPeer();
  BulletPeer(const BulletPeer&) = delete;
  BulletPeer& operator=(const BulletPeer&) = delete;

  // One fixed step of dt: stepSimulation(dt, 0), no interpolation, no sub-stepping.
  void step();

  int contactPoints() const;        // points in all persistent manifolds, after the last step
  Vec3 position(size_t body) const;  // centre of the model's body `body` [m]
  bool finite() const;              // every body's position is finite

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace substep::bench

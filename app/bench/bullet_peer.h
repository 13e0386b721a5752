// The Bullet peer of substep-bench: a scene rebuilt in Bullet 3 (btDiscreteDynamicsWorld,
// sequential impulse solver), started from the same coordinates as our World, so both engines
// step the very same initial state. Bullet's headers stay inside bullet_peer.cpp.
//
// Shapes: sphere, box, capsule and cylinder (axis along local Y in both engines), static planes.
// Joints: ball -> btPoint2PointConstraint, hinge (limits) -> btHingeConstraint, cone-twist ->
// btConeTwistConstraint, fixed -> btFixedConstraint. docs/benchmarks.md has the mapping and where
// it is only approximate.
#pragma once

#include "physics/math.h"
#include "physics/model.h"
#include "physics/state.h"

#include <memory>
#include <string>

namespace substep::bench {

// Why Bullet cannot build the model (empty if it can): convex and triangle meshes, springs,
// motors and hinge motors are not mapped.
std::string bulletUnsupported(const Model& model);

// Bullet's version as it reports it, e.g. "3.24 (float)": btScalar's precision.
std::string bulletVersion();

class BulletPeer {
 public:
  // Every body of `model` at its pose and velocity in `initial`, with the model's mass, principal
  // inertia, friction and restitution (Bullet's body frame = ours: centre of mass and principal
  // axes); static bodies have mass 0. Gravity from the model. Every joint of the model, with
  // collisions between its two bodies off unless Joint::collide. `iterations` solver iterations,
  // Bullet's defaults otherwise; no body ever sleeps (DISABLE_DEACTIVATION on every body).
  // Throws std::invalid_argument for unsupported models.
  BulletPeer(const Model& model, const State& initial, double dt, int iterations);
  ~BulletPeer();
  BulletPeer(const BulletPeer&) = delete;
  BulletPeer& operator=(const BulletPeer&) = delete;

  // One fixed step of dt: stepSimulation(dt, 0), no interpolation, no sub-stepping.
  void step();

  int contactPoints() const;        // points in all persistent manifolds, after the last step
  Vec3 position(size_t body) const;  // centre of mass of the model's body `body` [m]
  Pose pose(size_t body) const;      // centre of mass and body-to-world rotation
  Vec3 velocity(size_t body) const;  // linear velocity [m/s]
  bool finite() const;              // every body's position is finite

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace substep::bench

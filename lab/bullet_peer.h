// The Bullet peer of the lab and substep-bench: a scene rebuilt in Bullet 3
// (btDiscreteDynamicsWorld, sequential impulse solver), started from the same coordinates as our
// World, so both engines step the very same initial state. Bullet's headers stay inside
// bullet_peer.cpp. The lab names it as a method, `bullet:it=10` (physics/settings.h).
//
// Shapes: sphere, box, capsule and cylinder (axis along local Y in both engines), static planes.
// Joints: ball -> btPoint2PointConstraint, hinge (limits) -> btHingeConstraint, cone-twist ->
// btConeTwistConstraint, fixed -> btFixedConstraint. Friction and restitution of a pair combine
// as ours do (geometric mean, maximum). docs/benchmarks.md has the mapping and where it is only
// approximate.
#pragma once

#include "physics/math.h"
#include "physics/model.h"
#include "physics/run.h"
#include "physics/state.h"

#include <memory>
#include <string>

namespace substep::lab {

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
  // Throws std::invalid_argument for unsupported models. `gyroscopic` is Bullet's own term
  // (BT_ENABLE_GYROSCOPIC_FORCE_IMPLICIT_BODY, on by default in Bullet; off: none, as the report).
  BulletPeer(const Model& model, const State& initial, double dt, int iterations, bool gyroscopic = true);
  ~BulletPeer();
  BulletPeer(const BulletPeer&) = delete;
  BulletPeer& operator=(const BulletPeer&) = delete;

  // One fixed step of dt: stepSimulation(dt, 0), no interpolation, no sub-stepping.
  void step();

  int contactPoints() const;        // points in all persistent manifolds, after the last step
  Vec3 position(size_t body) const;  // centre of mass of the model's body `body` [m]
  Pose pose(size_t body) const;      // centre of mass and body-to-world rotation
  Vec3 velocity(size_t body) const;  // linear velocity [m/s]
  Vec3 angularVelocity(size_t body) const;  // world frame [rad/s]
  // The state of every body, as our State holds it (angular velocity in the body frame).
  void state(State& out) const;
  // Depths of the touching points in all persistent manifolds after the last step: the deepest
  // and the sum of squares and count over the penetrating points [m], by Bullet's distances.
  struct Penetration {
    double deepest = 0, sumSquares = 0;
    int points = 0;
  };
  Penetration penetration() const;
  bool finite() const;              // every body's position is finite

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The peer as the run driver steps it (physics/run.h): its state read back into substep's after
// each step, outside the timed part.
class BulletEngine final : public Engine {
 public:
  BulletEngine(const Model& model, const State& initial, double dt, int iterations, bool gyroscopic)
      : peer_(model, initial, dt, iterations, gyroscopic), s_(initial), dt_(dt) {}
  void advance() override { peer_.step(); }
  Step status() override;
  const State& state() const override { return s_; }
  ContactDepths depths() const override;
  const BulletPeer& peer() const { return peer_; }

 private:
  BulletPeer peer_;
  State s_;
  double dt_;
};

}  // namespace substep::lab

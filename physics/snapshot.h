// What a step leaves to look at: every body's state and, for the inspector and the force arrows,
// the step's contacts and joints. The live session keeps these as its history (the timeline), a
// recording (physics/recording.h) stores them, and frames are drawn from them, so what the page,
// a recording and a video show is one set of numbers.
//
// Body states are the World's doubles, bit for bit (a recording replays a trajectory exactly);
// contacts and joints are floats: they are read, never stepped from, and they are most of the
// bytes (docs/recordings.md).
#pragma once

#include "physics/state.h"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace substep {

class World;
struct Model;

using Vec3f32 = Eigen::Vector3f;

// A contact point at the end of the step.
struct ContactSnap {
  Vec3f32 point = Vec3f32::Zero();   // midway between its anchors on the two bodies, world [m]
  Vec3f32 normal = Vec3f32::UnitY(); // from body b to body a, world
  float depth = 0;                   // penetration at the step's end coordinates (> 0: overlapping) [m]
  float normalImpulse = 0;           // λn of the step's last sub-step [N s]
};

// A touching pair: its points are ContactSnaps [first, first + count).
struct ManifoldSnap {
  int32_t a = -1, b = -1;            // bodies; the normal points from b to a
  int32_t first = 0, count = 0;
  Vec3f32 friction = Vec3f32::Zero();  // tangential friction impulse on a, world [N s]
  float twist = 0;                   // twist friction impulse about the normal [N m s]
};

// A joint of the model (same index), at the end of the step.
struct JointSnap {
  float error = 0;                   // anchor separation (jointError) [m]
  Vec3f32 linear = Vec3f32::Zero();  // the impulse its rows put on body A's translation, world [N s]
  Vec3f32 angular = Vec3f32::Zero(); // ... on A's rotation, world [N m s]
};

struct Snapshot {
  State state;                       // time, step, every body
  std::vector<ManifoldSnap> manifolds;
  std::vector<ContactSnap> contacts;
  std::vector<JointSnap> joints;     // empty when the world has not stepped (t = 0)
  std::vector<int32_t> asleep;       // bodies asleep after the step (SolverSettings::sleep), increasing

  double deepest() const;            // largest depth of a contact point [m], 0 when none
  double worstJointError() const;    // [m]
};

// The world as it is now (after its last step).
Snapshot takeSnapshot(const World& world);
// A state without contacts or impulses (t = 0, or a peer engine's state), joint errors measured.
Snapshot takeSnapshot(const Model& model, const State& state);

}  // namespace substep

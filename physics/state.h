// The mutable state of a simulation. Angular velocity is stored in the body frame, as the
// report's section III does (the local counterpart v̌ of the angular velocity), so that the
// rotational inverse mass M̌⁻¹ is the constant diagonal of the model.
#pragma once

#include "physics/math.h"

#include <vector>

namespace substep {

struct BodyState {
  Vec3 x = Vec3::Zero();       // centre of mass, world [m]
  Quat q = Quat::Identity();   // body to world rotation
  Vec3 v = Vec3::Zero();       // linear velocity, world [m/s]
  Vec3 w = Vec3::Zero();       // the report's _r v̌: angular velocity in the body frame [rad/s]

  Pose pose() const { return Pose{x, q}; }
  Vec3 worldAngularVelocity() const { return q * w; }
};

struct State {
  double time = 0;             // [s]
  long long step = 0;
  std::vector<BodyState> bodies;

  bool finite() const;
};

}  // namespace substep

// What ConstraintSet::build takes of a world besides its manifolds, for tests that build a set
// beside the world's: every body's pose, and its mass as an awake world gives it to the steppers
// (zero for static bodies).
#pragma once

#include "physics/world.h"

#include <vector>

namespace substep {

struct StepInputs {
  std::vector<Pose> poses;
  std::vector<BodyMass> mass;
};

inline StepInputs stepInputs(const World& w) {
  StepInputs in;
  for (size_t i = 0; i < w.model().bodies.size(); ++i) {
    const Body& body = w.model().bodies[i];
    in.poses.push_back(w.state().bodies[i].pose());
    in.mass.push_back(body.isStatic ? BodyMass{} : BodyMass{body.invMass, body.invInertia});
  }
  return in;
}

}  // namespace substep

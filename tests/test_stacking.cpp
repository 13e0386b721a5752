// Resting contact: a box on the ground and a stack of five stay put under A2 (the report's
// iterative essential stepping, no warm starting), and A1's direct solve meets its residual.
#include "physics/scene_file.h"
#include "physics/world.h"

#include <gtest/gtest.h>

using namespace substep;

namespace {

struct RestResult {
  double maxMove = 0;      // largest displacement of any body from its start [m]
  double maxSpeed = 0;     // largest speed at the end [m/s]
  double maxPenetration = 0;
  double maxResidual = 0;
};

RestResult rest(const std::string& file, const SolverOverrides& o, double seconds) {
  const Scene s = loadScene(std::string(SUBSTEP_SOURCE_DIR) + "/assets/scenes/" + file);
  const SolverSettings st = resolve(s.solver.merged(o));
  World w(s.model, st, s.initial);
  RestResult r;
  const int steps = static_cast<int>(std::lround(seconds / st.dt));
  for (int k = 0; k < steps; ++k) {
    const StepReport& rep = w.step();
    EXPECT_TRUE(rep.finite);
    r.maxResidual = std::max(r.maxResidual, rep.solver.residual);
    r.maxPenetration = std::max(r.maxPenetration, w.maxPenetration());
    for (size_t i = 0; i < s.model.bodies.size(); ++i)
      r.maxMove = std::max(r.maxMove, (w.state().bodies[i].x - s.initial.bodies[i].x).norm());
  }
  for (const BodyState& b : w.state().bodies) r.maxSpeed = std::max(r.maxSpeed, b.v.norm());
  return r;
}

SolverOverrides algo(Algorithm a) {
  SolverOverrides o;
  o.algorithm = a;
  return o;
}

}  // namespace

// A unit box on the ground, 10 s of A2 at its defaults (10 iterations, no warm start): it sinks
// to the allowed penetration (1 mm) and stays, within 2 mm, at under 1 mm/s.
TEST(Resting, BoxOnGroundUnderA2) {
  const RestResult r = rest("box_on_ground.json", algo(Algorithm::A2), 10);
  EXPECT_LT(r.maxMove, 0.002);
  EXPECT_LT(r.maxSpeed, 0.001);
  EXPECT_LT(r.maxPenetration, 0.002);
}

// Five unit boxes, 10 s of A2 at its defaults: every contact sinks to the slop (the top box by
// 5 mm) and Gauss-Seidel leaves some sway; bounds: 1.5 cm, 1 cm/s.
TEST(Resting, StackOfFiveUnderA2) {
  const RestResult r = rest("stack.json", algo(Algorithm::A2), 10);
  std::printf("stack of 5, A2, 10 s: moved %.2f mm, final speed %.2f mm/s, penetration %.2f mm\n", r.maxMove * 1e3,
              r.maxSpeed * 1e3, r.maxPenetration * 1e3);
  EXPECT_LT(r.maxMove, 0.015);
  EXPECT_LT(r.maxSpeed, 0.01);
  EXPECT_LT(r.maxPenetration, 0.005);
}

// A1 solves each step's MLCP to a residual of 1e-9 and holds the stack exactly at the slop.
TEST(Resting, StackOfFiveUnderA1) {
  const RestResult r = rest("stack.json", algo(Algorithm::A1), 5);
  EXPECT_LT(r.maxResidual, 1e-9);
  EXPECT_LT(r.maxMove, 0.0051);  // 5 contacts × 1 mm of slop, plus round-off
  EXPECT_LT(r.maxSpeed, 1e-6);
}

TEST(Resting, PendulumChainUnderA1MeetsTheResidual) {
  const RestResult r = rest("pendulum_chain.json", algo(Algorithm::A1), 3);
  EXPECT_LT(r.maxResidual, 1e-9);
}

// The MuJoCo peer of the lab: a scene written as MJCF, loaded by MuJoCo 2.2.2 (Debian's
// libmujoco) from its virtual file system, started from the same coordinates as our World, and
// stepped by mj_step. MuJoCo's headers stay inside mujoco_peer.cpp. The lab names it as a method,
// `mujoco:solver=newton:it=100:integrator=euler:cone=pyramidal:margin=0.001` (physics/settings.h,
// lab/peers.h).
//
// MuJoCo works in generalized coordinates: its joints are a tree. Every dynamic body is a MuJoCo
// body with our frame (centre of mass, principal axes: <inertial> at the origin with our mass and
// diagonal inertia); static bodies are bodies welded to the world. Joints are walked from the static
// bodies outwards: a body reached by a ball or hinge joint is the child of the body it joins, on a
// MuJoCo ball or hinge joint at the child's anchor (a hinge's limits as its range), one reached by a
// fixed joint is welded to it (a child without a joint); a body reached by none is a <freejoint/>
// body. A ball or fixed joint that closes a loop is an equality (connect, weld). Contacts: shapes
// sphere, box, capsule, cylinder and static planes, with our filter (categories, masks, filter groups,
// joints without `collide`) as MuJoCo excludes, our friction combination (the geometric mean;
// MuJoCo takes the larger: pairs whose two differ are explicit <pair>s), condim 3, MuJoCo's own
// soft contacts otherwise (solref 0.02 1). Refused: meshes, dynamic planes, cone-twist joints,
// springs, motors, a hinge that closes a loop, restitution (MuJoCo has no coefficient of
// restitution: its contacts are damped springs), initial velocities the joints cannot hold.
#pragma once

#include "physics/model.h"
#include "physics/run.h"
#include "physics/state.h"

#include <memory>
#include <string>

namespace substep::lab {

std::string mujocoUnsupported(const Model& model, const State& initial);

std::string mujocoVersion();  // "2.2.2"

struct MujocoSettings {
  double dt = 1.0 / 60;
  int iterations = 100;     // the solver's iteration cap (MuJoCo's default 100)
  int solver = 0;           // 0 newton, 1 cg, 2 pgs (the spec's order)
  int integrator = 0;       // 0 euler, 1 rk4, 2 implicit
  bool elliptic = false;    // the friction cone: pyramidal (MuJoCo's default) or elliptic
  double margin = 0.001;    // contacts found within [m], acting from touching (gap = margin)
};

// The MJCF the peer loads for a scene (for messages and tests); throws std::invalid_argument when
// mujocoUnsupported() says why not.
std::string mujocoXml(const Model& model, const State& initial, const MujocoSettings& settings);

// The peer as the run driver steps it; throws std::invalid_argument for models it cannot map.
std::unique_ptr<Engine> makeMujocoEngine(const Model& model, const State& initial, const MujocoSettings& settings);

}  // namespace substep::lab

// The ODE peer of the lab: a scene rebuilt in ODE 0.16 (Debian's libode, double precision), started
// from the same coordinates as our World, stepped by dWorldQuickStep (iterative, SOR) or dWorldStep
// (ODE's direct LCP solve). ODE's headers stay inside ode_peer.cpp. The lab names it as a method,
// `ode:it=20:sor=1.3:step=quick:erp=0.2:cfm=1e-10:layer=0.001` (physics/settings.h, lab/peers.h).
//
// Shapes: sphere, box, capsule and cylinder (ODE's axis is local Z, ours Y: the geom is turned by an
// offset), static planes. Joints: ball -> dJointCreateBall, hinge -> dJointCreateHinge with its
// limits as stops, fixed -> dJointCreateFixed. Contacts: every pair our filter admits (categories,
// masks, filter groups, joints without `collide`), up to 8 points a pair, Coulomb friction by ODE's
// pyramid (dContactApprox1) with our combination (geometric mean of the frictions, the larger
// restitution, bouncing from 1 m/s of approach: substep's restitution_threshold default). Masses
// and principal inertias as given (dMassSetParameters in the body frame, which is ours: centre of
// mass and principal axes). No body ever sleeps (ODE's auto-disable is off).
#pragma once

#include "physics/model.h"
#include "physics/run.h"
#include "physics/state.h"

#include <memory>
#include <string>

namespace substep::lab {

// Why ODE cannot build the model from `initial` (empty if it can): meshes, dynamic planes,
// cone-twist joints (ODE has no swing cone), springs, motors and hinge motors are not mapped, nor
// hinge limits beyond half a turn from the start (ODE's stops are in [-pi, pi]).
std::string odeUnsupported(const Model& model, const State& initial);

// "0.16.2 (double)": the library's configuration as it reports it.
std::string odeVersion();

struct OdeSettings {
  double dt = 1.0 / 60;
  int iterations = 20;      // QuickStep's sweeps (dWorldSetQuickStepNumIterations)
  double sor = 1.3;         // QuickStep's over-relaxation (dWorldSetQuickStepW)
  bool quick = true;        // dWorldQuickStep; false: dWorldStep
  double erp = 0.2, cfm = 1e-10;  // the world's, for joints and contacts
  double layer = 0.001;     // the contact surface layer (dWorldSetContactSurfaceLayer) [m]
  bool gyroscopic = true;   // ODE's gyroscopic mode (its default, on)
};

// The peer as the run driver steps it (physics/run.h): its state read back into substep's after each
// step, outside the timed part. Throws std::invalid_argument for models it cannot map.
std::unique_ptr<Engine> makeOdeEngine(const Model& model, const State& initial, const OdeSettings& settings);

}  // namespace substep::lab

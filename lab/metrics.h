// What a run measured (docs/lab.md, "Metrics"). A Probe watches a run state by state, the same
// way for substep's World and for the Bullet peer, and keeps the figures of one record.
#pragma once

#include "lab/reference.h"
#include "physics/constraints/joints.h"
#include "physics/failure.h"
#include "physics/run.h"
#include "physics/scene_file.h"

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace substep::lab {

// Per kind of joint ("ball", "hinge", ...): anchor separation and angular error.
struct JointKindError {
  double max = 0, rms = 0;  // anchor separation over every (step, joint) of the kind [m]
  double angleMax = 0;      // hinge axes apart, fixed joint turned [rad]
  long long samples = 0;
  double sumSquares = 0;
};

struct Metrics {
  int joints = 0;                               // in the scene: joint figures are measured when > 0
  // Contacts: every penetrating contact point of every step (depth > 0).
  double penetrationMax = 0, penetrationRms = 0, penetrationEnd = 0;  // [m]
  // Joints: every (step, joint).
  double jointErrorMax = 0, jointErrorRms = 0;  // anchor separation [m]
  double jointAngleErrorMax = 0;                // [rad]
  std::map<std::string, JointKindError> byKind;
  LimitExcess limitExcess;                      // largest over the run, per kind of limit [rad]
  // Energy: kinetic plus potential. Drifts are shares of the largest kinetic energy of the run
  // (the energy in play), measured on conservative scenes only.
  double energyStart = 0, energyEnd = 0;        // [J]
  std::optional<double> energyDrift;            // largest |E(t) - E(0)| / scale
  std::optional<double> energyDriftEnd;         // (E(end) - E(0)) / scale, signed
  // Momentum, on free scenes (no gravity, no static body): shares of the start's.
  std::optional<double> linearMomentumDrift, angularMomentumDrift;
  // Resting bodies (the scene's "rest" list, else every dynamic body).
  double jitter = 0;                            // largest speed in the run's second half [m/s]
  double displacementMax = 0;                   // largest distance from the start [m]
  std::string displacementBody;
  double sidewaysMax = 0;                       // ... across gravity: a stack's settling left out [m]
  std::string sidewaysBody;
  std::optional<double> collapseTime;           // first time a resting body moved beyond the tolerance [s]
  std::string collapseRule;                     // "moved > 0.05 m", or the failure watch's rule
  double speedMax = 0;                          // fastest body [m/s]
  FailureReport failure;                        // sag / collapse / divergence (physics/failure.h)
  // References.
  std::optional<double> trajectoryError, trajectoryErrorRms;  // [m]
  std::optional<double> referenceError;         // relative error of the closed form's quantity
  std::string referenceText;                    // e.g. "period 2.0071 s, closed form 2.0064 s"
  std::optional<double> periodMeasured, periodReference;  // pendulum [s]
  // The scene's own checks.
  std::optional<double> movingLeast;            // the least a "moving" body moved by the end [m]
  std::optional<bool> stayedIn;
  std::optional<double> turnedMost;             // the most the "turns" axis turned [rad]
};

// A quantity of criterionMetrics() (physics/scene_file.h) from the metrics; nullopt when the run
// does not measure it (no joints, not conservative, no reference).
std::optional<double> metricValue(const Metrics& m, const std::string& name);
// Its unit and a short label for tables and charts: "m", "max joint error".
const char* metricUnit(const std::string& name);
const char* metricLabel(const std::string& name);
// A value as people read it: lengths in mm, cm or m, angles in degrees, shares in percent,
// speeds in m/s, to three significant digits: "3.14 cm", "12.3 deg", "0.52 %".
std::string formatMetric(const std::string& name, double value, int extraDigits = 0);
// A length alone, the same way.
std::string formatLength(double metres, int extraDigits = 0);
// "max joint error 1.004 cm > 1.000 cm": the quantity against its bound, with the digits it takes
// for two different figures not to print the same.
std::string comparisonText(const std::string& metric, double value, const char* op, double bound);

// What a reference needs of a run, prepared once per scene (the converged run costs).
struct PreparedReference {
  SceneReference::Kind kind = SceneReference::Kind::Converged;
  std::optional<PendulumModel> pendulum;
  std::optional<ConvergedReference> converged;
};
// Throws ReferenceError (a converged run that fails its check) or std::invalid_argument.
PreparedReference prepareReference(const Scene& scene, const SceneReference& ref, double seconds);
// The grid trajectories are compared on [s].
constexpr double kTrajectoryInterval = 1.0 / 120;

// A run's observer (physics/run.h): after each step it measures the state and its contacts, and it
// stops the run when the failure watch sees it diverge.
class Probe final : public RunObserver {
 public:
  Probe(const Scene& scene, double seconds, const PreparedReference* reference = nullptr);
  void observe(const Engine& e, const StepRecord& r) override { observe(e.state(), e.depths(), r.finite); }
  std::string stop(const Engine&) override;
  bool stopIsDivergence() const override { return true; }
  // After each step: the state, its contacts, and whether it is still finite.
  void observe(const State& s, const ContactDepths& contacts, bool finite);
  // Once, after the last step.
  const Metrics& finish();
  const Metrics& metrics() const { return m_; }
  // The failure watch's divergence: a value beyond the world's limits, or the mechanical energy
  // grown by more than 100 times the energy that lifts every body by its size (physics/failure.h).
  bool diverged() const { return watch_.report().divergeTime >= 0; }

 private:
  const Scene& scene_;
  const Model& model_;
  double seconds_;
  const PreparedReference* reference_;
  Metrics m_;
  FailureWatch watch_;
  std::vector<int> rest_;
  bool conservative_ = false, free_ = false;
  Vec3 down_ = -Vec3::UnitY();  // gravity's direction (unit); -y without gravity
  double keMax_ = 0;
  Vec3 p0_ = Vec3::Zero(), l0_ = Vec3::Zero();
  double penSum_ = 0;
  long long penCount_ = 0, jointSamples_ = 0;
  double jointSum_ = 0;
  std::vector<double> times_, angles_;  // pendulum
  std::optional<TrajectorySampler> sampler_;
  double freeFallMax_ = 0, freeFallSum_ = 0, pendulumMax_ = 0, pendulumSum_ = 0;
  long long freeFallCount_ = 0, pendulumCount_ = 0;
  std::vector<Vec3> l0Bodies_;  // torque-free: each body's world angular momentum at the start
  double torqueFreeDrift_ = 0;
  State last_;
};

}  // namespace substep::lab

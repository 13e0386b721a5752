// References a run is measured against (docs/lab.md, "References"):
//   closed forms   the period of a pendulum, simple or physical, at any amplitude (the complete
//                  elliptic integral K); its angle over time (Jacobi's sn); free fall; the
//                  invariants of torque-free rotation (world angular momentum, energy)
//   converged run  one of substep's algorithms at a small h, accepted only if halving h moves the
//                  trajectory by less than a stated share of the motion
#pragma once

#include "physics/scene_file.h"

#include <chrono>
#include <stdexcept>
#include <string>
#include <vector>

namespace substep::lab {

// The complete elliptic integral of the first kind K(k), modulus k in [0, 1) (std::comp_ellint_1).
double ellipticK(double k);
// Jacobi's elliptic sine sn(u, k) (descending Landen transformation).
double jacobiSn(double u, double k);

// A body swinging about a fixed pivot, as the closed form sees it: the plane it swings in, the
// moment of inertia about the pivot's axis, the amplitude from its start (position and speed).
struct PendulumModel {
  int body = -1;
  Vec3 pivot = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ();   // normal of the swing plane
  Vec3 down = -Vec3::UnitY();  // along gravity
  double distance = 0;         // pivot to centre of mass [m]
  double inertia = 0;          // about the axis through the pivot [kg m^2]
  double omega0 = 0;           // small-amplitude angular frequency sqrt(m g d / I) [rad/s]
  double theta0 = 0;           // the angle at the start [rad]
  double amplitude = 0;        // the largest angle the swing reaches [rad]
  bool fromRest = true;        // released at rest (the angle over time is then known too)

  double smallPeriod() const;  // 2π/ω0 [s]
  double period() const;       // 4 K(sin(amplitude/2)) / ω0 [s]
  double angleAt(double t) const;   // the closed form's angle (fromRest only) [rad]
  double angleOf(const Vec3& x) const;  // the angle of a centre of mass at x [rad]
  Vec3 positionAt(double t, const Vec3& x0) const;  // the closed form's centre of mass
};
// Throws std::invalid_argument when the scene cannot be such a pendulum (no gravity, the body at
// the pivot, moving out of its plane, beyond the top).
PendulumModel pendulumModel(const Scene& scene, const SceneReference& ref);

// The period of a swing from its angle samples: the times the angle crosses zero (interpolated
// between samples), two crossings a period. NaN with fewer than three crossings.
double measuredPeriod(const std::vector<double>& times, const std::vector<double>& angles);

// Positions of a scene's dynamic bodies on a grid of times (every `interval` from 0), filled in
// by linear interpolation between the steps around each grid time.
class TrajectorySampler {
 public:
  TrajectorySampler(const Model& model, const State& initial, double interval);
  void observe(const State& s);  // after each step
  double interval() const { return interval_; }
  // samples()[k][i]: the i-th dynamic body at time k·interval.
  const std::vector<std::vector<Vec3>>& samples() const { return samples_; }
  const std::vector<int>& bodies() const { return bodies_; }

 private:
  double interval_;
  std::vector<int> bodies_;
  double lastTime_ = 0;
  std::vector<Vec3> last_;
  std::vector<std::vector<Vec3>> samples_;
};

// Largest and RMS distance between two trajectories on the same grid, over their common samples
// and bodies [m].
struct TrajectoryDifference {
  double max = 0, rms = 0;
  size_t samples = 0;
};
TrajectoryDifference difference(const TrajectorySampler& a, const TrajectorySampler& b);

// A reference that did not pass its own check; the message says why and what to do.
struct ReferenceError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Wall time given to a computation ran out before it had an answer; the message says how far it got.
struct TimeBudgetSpent : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The converged run: the scene under the reference's method at h and at h/2 for `seconds`;
// accepted when the two differ by at most `change` of the motion (the largest displacement of a
// body in the finer run), and then the finer run is the reference. Throws ReferenceError, or
// TimeBudgetSpent when the wall clock passes `deadline` during the runs.
struct ConvergedReference {
  std::string method;             // as stated, e.g. "a1:h=1/960"
  double dt = 0;                  // the finer run's [s]
  TrajectorySampler trajectory;   // the finer run's
  double change = 0;              // the halving's change [m]
  double motion = 0;              // [m]
};
ConvergedReference convergedReference(const Scene& scene, const SceneReference& ref, double seconds, double interval,
                                      std::chrono::steady_clock::time_point deadline = std::chrono::steady_clock::time_point::max());

}  // namespace substep::lab

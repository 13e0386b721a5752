// How a structure fails, told apart (docs/algorithms.md, "Where sub-stepping fails"):
//   sag         bodies settle downwards, a few centimetres, and the structure stands
//   collapse    a body is displaced sideways by more than half its size, or the structure's top
//               falls by more than the size of the body that was on top
//   divergence  a value is not finite or beyond the world's limits, or the mechanical energy
//               has grown by more than 100 times the energy in play at the start: what lifts
//               every body by its size, plus the kinetic energy (without gravity, only that)
// A FailureWatch observes a run state by state and records when each first happened.
#pragma once

#include "physics/model.h"
#include "physics/state.h"

#include <string>
#include <vector>

namespace substep {

struct FailureCriteria {
  double sagTolerance = 0.005;  // a downward settling beyond this is reported as sag [m]
  double energyFactor = 100;    // divergence: energy gained beyond this many times Σ m g size
};

struct FailureReport {
  double sagTime = -1;          // first time a body had settled more than sagTolerance [s]; -1: never
  double collapseTime = -1;     // [s]; -1: never
  double divergeTime = -1;      // [s]; -1: never
  double maxSag = 0;            // largest downward displacement of a body while standing [m]
  double maxSideways = 0;       // largest sideways displacement of a body [m]
  double maxSpeed = 0;          // largest speed of a body (ejection speed, when it collapses) [m/s]
  double maxEnergyGain = 0;     // largest gain of mechanical energy over the start [J]
  std::string collapsedBody;    // the first body that moved sideways too far, or "top"
  bool stands() const { return collapseTime < 0 && divergeTime < 0; }
  std::string verdict() const;  // "stands (sag 2.1 cm)", "collapses at 0.42 s", "diverges at 3.1 s"
};

class FailureWatch {
 public:
  FailureWatch(const Model& model, const State& initial, const FailureCriteria& criteria = {});
  // Observes the state at its time; `finite` false when the world reported a diverged step.
  void observe(const State& s, bool finite = true);
  const FailureReport& report() const { return report_; }

 private:
  const Model& model_;
  FailureCriteria criteria_;
  std::vector<Vec3> x0_;
  std::vector<double> size_;    // per body: half its smallest dimension (sideways tolerance) [m]
  Vec3 up_;
  int top_ = -1;                // the body highest at the start
  double topHeight0_ = 0, topSize_ = 0;
  double energy0_ = 0, energyScale_ = 0;
  FailureReport report_;
};

// The dynamic body that moved furthest from where it started (of `only`, when given).
struct Displacement {
  double metres = 0;
  int body = -1;
  Vec3 by = Vec3::Zero();
};
Displacement largestDisplacement(const Model& model, const State& from, const State& now,
                                 const std::vector<int>* only = nullptr);

// Energies of a state's dynamic bodies [J]: kinetic Σ ½ m |v|² + ½ v̌ᵀ I v̌, potential Σ -m g·x,
// mechanical their sum.
double kineticEnergy(const Model& model, const State& s);
// One body's: ½ m |v|² + ½ v̌ᵀ I v̌ (angular velocity in the body frame) [J].
double kineticEnergy(const Body& b, const BodyState& x);
double potentialEnergy(const Model& model, const State& s);
double mechanicalEnergy(const Model& model, const State& s);

}  // namespace substep

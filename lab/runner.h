// One run of the lab: a scene under a method for some seconds of simulated time, its cost timed
// and its metrics measured, the same way for substep's algorithms and the Bullet peer, in this
// process. Cost is the median over repeats; the metrics are the first repeat's (every engine here
// is deterministic, so the repeats step the same states).
#pragma once

#include "lab/method.h"
#include "lab/metrics.h"
#include "physics/state_hash.h"
#include "physics/world.h"

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace substep::lab {

struct Cost {
  double msPerStep = 0;                 // median over the repeats of each one's mean step [ms]
  std::optional<StageTimes> stages;     // s1..s4 of the median repeat [ms per step] (substep only)
  std::vector<double> repeats;          // each repeat's mean step [ms]
};

struct RunSetup {
  double seconds = 3;                   // simulated time [s]
  int repeat = 1;                       // timed runs; the cost is their median
  std::optional<double> dt;             // a sweep's time step (else the method's, else the scene's)
  double frameRate = 0;                 // keep the state this many times a simulated second (clips)
  const PreparedReference* reference = nullptr;
  // Asked after every step of the first run with the metrics so far and the time: a non-empty
  // answer stops the run there (advice stops a run once it has missed its target).
  std::function<std::string(const Metrics&, double)> stop;
  // Where to write the run's recording (physics/recording.h), "" for none: every
  // `recordEvery`-th step of the first run, committed when the run ends by its plan or a divergence.
  std::string recording;
  long long recordEvery = 1;
};

struct RunResult {
  Method method;
  SolverSettings settings;              // what it ran with (the Bullet peer: dt, iterations, gyroscopic)
  long long steps = 0;                  // planned
  long long stepsDone = 0;
  double time = 0;                      // simulated time reached [s]
  bool finite = true;                   // false: a value went non-finite or beyond the world's limits
  bool diverged = false;                // the run diverged (not finite, or its energy exploded): it stopped there
  bool refused = false;                 // the method cannot run this scene (A1's size limit, Bullet's mapping)
  std::string stopped;                  // why the run ended before `steps` (divergence, refusal)
  std::string stoppedEarly;             // the stop callback's reason
  Cost cost;
  Metrics metrics;
  std::vector<State> frames;            // at frameRate, from t = 0
  RunHashes hashes;                     // of the observed pass, to re-run it against
  std::string recording;                // the recording written (RunSetup::recording), "" if none; a
                                        // record names it relative to its own folder instead
  double msPerSecond() const { return cost.msPerStep / settings.dt; }  // cost of a simulated second [ms]
};

// Throws std::invalid_argument for settings the scene cannot take (they are checked before any
// run); a method that cannot run the scene is a result with `refused`, a divergence one with
// finite = false.
RunResult runMethod(const Scene& scene, const Method& method, const RunSetup& setup);


}  // namespace substep::lab

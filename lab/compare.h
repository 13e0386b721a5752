// The engine comparison of Erez, Tassa and Todorov ("Simulation tools for model-based robotics:
// comparison of Bullet, Havok, MuJoCo, ODE and PhysX", ICRA 2015), reproduced on a sweep's records:
// per scene, each method's runs over h as points of (real-time factor, error against the scene's
// reference), and who leads where. The charts are lab/chart.h's `speed` kind; `substep compare`
// runs the sweep (assets/sweeps/compare.json) and writes both.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace substep::lab {

// One run as the comparison sees it.
struct ComparedRun {
  std::string method;      // as the sweep ran it, h included
  std::string curve;       // the method without its h: the curve it is a point of
  std::string h;           // "1/60"
  double speed = 0;        // real-time factor: simulated seconds per wall-clock second (one core)
  double error = 0;        // the scene's error metric
};

struct SceneComparison {
  std::string scene, metric;          // metric: criterionMetrics()' name
  std::vector<ComparedRun> front;     // runs no other is both faster and more accurate than, fastest first
  std::string leader;                 // the curve with the most runs on the front (ties: the fastest of them)
  ComparedRun mostAccurate, fastest;  // over every finite run
  std::vector<std::string> diverged;  // methods (h included) that diverged
  std::vector<std::string> refused;   // "ode: joint \"x\" is a cone_twist ...", once per curve
};

// Per scene, in the order the records first name them. Rows are sweep records (lab/record.h).
std::vector<SceneComparison> compareRuns(const std::vector<nlohmann::json>& rows);

// The table of who leads where (markdown), one row per scene, then what each peer refused.
std::string comparisonTable(const std::vector<SceneComparison>& scenes);

}  // namespace substep::lab

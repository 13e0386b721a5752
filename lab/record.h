// A run as one JSON record: one line of a sweep's JSONL output, and the atlas's cells. Every
// setting, every metric, the cost, the verdict and the source commit (docs/lab.md, "Records").
#pragma once

#include "lab/runner.h"
#include "lab/verdict.h"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>

namespace substep::lab {

// The quantity a scene's criteria make its "error": the criteria's "error", else the first
// quantity its pass criteria bound, else the trajectory error when a reference gives one (the
// reference's own error for torque-free rotation); nullopt when the scene states none.
std::optional<std::string> statedErrorMetric(const Scene& scene);
// The quantity a scene's charts and advice call "error": the stated one, else the largest joint
// error when the scene has joints, else the largest penetration.
std::string errorMetric(const Scene& scene);

// Where a run sits in a sweep: which plan (a hash of every run's key, in order), its index, and
// how many runs the plan has. Merging checks rows against it.
struct SweepPlace {
  std::string plan;
  long long index = 0, runs = 0;
};

// What identifies a run: the scene, the method, the time step, the simulated time, and the
// reference it is measured against when the scene states one. A sweep skips runs whose key is
// already in its output.
std::string runKey(const Scene& scene, const std::string& method, double dt, double seconds);

// The scene's name in records: the file's stem ("chain", "tall_stack_30").
std::string sceneName(const Scene& scene);

// What a record needs to be re-run (substep rerun, lab/rerun.h), added to it: the scene (as given,
// its absolute path and its content's hash), the engine, every setting, the planned steps and
// those done, the source commit, the threads a step used, and the state hashes (the last state's
// as state_hash, the checkpoints under state_hashes).
void addReproduction(nlohmann::json& record, const Scene& scene, const std::string& engine, const nlohmann::json& settings,
                     long long steps, long long stepsDone, const RunHashes& hashes);
nlohmann::json hashesJson(const RunHashes& h);
// Throws std::invalid_argument naming what is missing or malformed.
RunHashes hashesFromJson(const nlohmann::json& j);
// The settings a record holds for a method: every resolved setting (a peer's: dt, iterations, its
// gyroscopic term and its own keys, lab/peers.h).
nlohmann::json recordSettingsJson(const Method& m, const SolverSettings& s);

// One panel of a recording: what it shows (a method's text, or "" for a scene's own settings),
// its resolved settings as a record holds them (recordSettingsJson), and its engine.
struct RecordingPanel {
  std::string name;
  nlohmann::json settings;
  std::string method;    // the spec it ran, when a method was given
  std::string engine = "substep";  // or the peer's name: "bullet", "ode", "mujoco"
};
// A recording's metadata (docs/recordings.md): the format and version, the scene (its file, the
// folder its meshes are found from, its text), the model's body and joint counts, the panels,
// `every` and the planned steps, and what addReproduction() writes of the run but what only its
// end knows (steps done, state hashes: the frames themselves are the run). The top-level settings
// and engine are the first panel's.
nlohmann::json recordingMeta(const Scene& scene, const std::vector<RecordingPanel>& panels, long long every, long long plannedSteps);

// A recording's file name in a folder of them: "<scene>-<method>.rec", with "-h<step>" when a
// sweep gave the time step, characters other than letters, digits, '.', '=', '_' and '-' as '_':
// "card_house-a5_n=4_m=1.rec", "chain-a2_m=4-h1_120.rec".
std::string recordingFileName(const Scene& scene, const std::string& method, const std::optional<double>& dt = std::nullopt);

nlohmann::json recordJson(const Scene& scene, const RunResult& run, double seconds, int repeat,
                          const std::optional<SweepPlace>& place = std::nullopt);

// The value of a criterion quantity in a record ("values" holds every one the run measured);
// nullopt when absent or null.
std::optional<double> recordValue(const nlohmann::json& row, const std::string& metric);

}  // namespace substep::lab

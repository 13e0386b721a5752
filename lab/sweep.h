// Sweeps: the cross product of scenes x methods x time steps, planned, sharded, resumed and
// merged (docs/lab.md, "Sweeps"). Running a planned run is the runner's (lab/runner.h); the
// `substep sweep` command writes one record per run (lab/record.h) to a JSONL file.
#pragma once

#include "lab/method.h"

#include <nlohmann/json.hpp>

#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace substep::lab {

// What a sweep runs, as a SPEC.json file or the command line gives it:
//   {"scenes": ["chain", "assets/scenes/pyramid.json"],
//    "methods": ["a2:m=4|10", "a5:n=1|2|4|8:m=1", "bullet:it=10"],   (or one string, comma-separated)
//    "dt": ["1/60", "1/120"],     optional: every method at each (a method that names h keeps it)
//    "repeat": 3,                 timed runs per run, the cost is their median (default 1)
//    "seconds": 2,                optional: else each scene's criteria "seconds", else 3
//    "reference": {...}}          optional: a reference for every scene, as a scene file states one
struct SweepSpec {
  std::vector<std::string> scenes;
  std::vector<std::string> methods;
  std::vector<double> dts;
  int repeat = 1;
  std::optional<double> seconds;
  std::optional<nlohmann::json> reference;
};
// Throws std::invalid_argument: "SPEC.json: methods[1]: ...".
SweepSpec readSweepSpec(const std::string& file);
// A time step as written: "1/60" or "0.005", checked against the settings table's range.
double parseStep(const std::string& text);

// A scene file with the sweep's reference put in its criteria (checked by the scene reader like
// any scene's). Throws SceneError.
Scene loadSweepScene(const std::string& path, const std::optional<nlohmann::json>& reference);

struct PlannedRun {
  size_t scene = 0;              // index into the plan's scenes
  Method method;
  std::optional<double> dt;      // the sweep's, when it gives one
  double seconds = 3;
  std::string key;               // runKey(): what a resumed sweep recognises
};

struct SweepPlan {
  std::vector<Scene> scenes;
  std::vector<PlannedRun> runs;  // scenes x methods x time steps, the last varying fastest
  std::string id;                // a hash of every key, in order: shards of one plan share it
};
// Throws std::invalid_argument for methods or time steps a scene cannot take.
SweepPlan planSweep(const SweepSpec& spec, std::vector<Scene> scenes);

// "i/N" (1 <= i <= N): shard i runs the plan's runs k with k mod N = i - 1.
struct Shard {
  int index = 1, count = 1;
  bool has(long long run) const { return run % count == index - 1; }
};
Shard parseShard(const std::string& text);  // throws std::invalid_argument

// The rows of a JSONL file. A last line cut short (a sweep killed while writing it) is left out
// and reported through `truncated`; any other bad line throws std::runtime_error naming the line.
std::vector<nlohmann::json> readRows(const std::string& file, bool* truncated = nullptr);

// Merging shards: rows by key, each once; per plan, every index present.
struct MergeResult {
  std::vector<nlohmann::json> rows;      // in plan order (plan, index), rows without a plan last
  std::vector<std::string> duplicates;   // keys seen more than once (the first kept)
  std::vector<std::string> gaps;         // "plan 3f2a...: runs 4, 9 of 12 missing"
};
MergeResult mergeRows(const std::vector<std::vector<nlohmann::json>>& files);

}  // namespace substep::lab

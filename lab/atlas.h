// The failure atlas (assets/scenes/atlas/, docs/lab.md): every atlas scene under a set of
// methods, each run judged by the scene's criteria. The verdicts come from the physics runs
// alone; `substep atlas` adds the page, the clips and the charts.
#pragma once

#include "lab/runner.h"
#include "lab/verdict.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace substep::lab {

// The default set: A1 and A2 (4 and 10 iterations) as the report has them, A3-A5 at Havok's
// 4-medium preset (n 4, m 1, kappa 1, tau 0.6: their defaults), the soft step and Bullet.
const char* defaultAtlasMethods();
// The atlas scenes: every .json in `folder`, by name.
std::vector<std::string> atlasScenes(const std::string& folder);

struct AtlasCell {
  RunResult run;
  Verdict verdict;
  double wallSeconds = 0;  // the run's own wall time
};

// One scene under every method, in order. frameRate > 0 keeps states for clips; a recordDir
// gets a recording of every cell's run (recordingFileName). A reference the scene states is
// prepared once (a converged run may refuse: ReferenceError). verdictsOnly stops a run once a
// bound is missed for good (boundMissed): the verdicts are the same, the figures and the wall
// times those of the run so far (the expected-table test; a 10-second pyramid_100 row otherwise).
std::vector<AtlasCell> runAtlasScene(const Scene& scene, const std::vector<Method>& methods, double frameRate = 0,
                                     int repeat = 1, const std::string& recordDir = "", bool verdictsOnly = false);

// The expected table (tests/data/atlas_expected.json): scene -> method -> "pass" / "fail" /
// "refused". Reading it throws std::runtime_error naming the file.
using VerdictTable = std::map<std::string, std::map<std::string, std::string>>;
VerdictTable readVerdicts(const std::string& file);
nlohmann::json verdictsJson(const VerdictTable& t);

}  // namespace substep::lab

// A record run again (substep rerun): the scene it names, checked against its content hash, stepped
// with the settings it holds, by the engine it names, for the steps it took, its state hashed at the
// same steps. The same to the last bit, or the first step where it is not and the bodies that
// differ there. A record is a run's metrics JSON (`substep run --metrics`), a line of a sweep's JSONL
// or of the atlas's atlas.jsonl: every one carries what addReproduction() writes (lab/record.h).
#pragma once

#include <nlohmann/json.hpp>

#include <functional>
#include <string>

namespace substep::lab {

struct RerunReport {
  enum class Result {
    Same,        // every hash the record holds, and the last state's, as the re-run's
    Differs,     // the first step where it does not, and the bodies there, in `text`
    Incomplete,  // the record lacks what a re-run needs, or its scene is gone or changed
  };
  Result result = Result::Same;
  std::string text;  // what was re-run and what came of it, one paragraph
};

// `where` names the record in messages ("out/m.json", "out/s.jsonl line 3"). `progress` is told
// (steps done, steps) as the re-run goes.
RerunReport rerunRecord(const nlohmann::json& record, const std::string& where,
                        const std::function<void(long long, long long)>& progress = {});

}  // namespace substep::lab

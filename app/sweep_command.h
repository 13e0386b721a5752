// A sweep as `substep sweep` runs it (app/cmd_sweep.cpp), for the commands built on one
// (`substep compare`).
#pragma once

#include "app/common.h"

#include <optional>
#include <string>
#include <vector>

namespace substep::app {

struct SweepOptions {
  std::string spec;
  std::vector<std::string> scenes, methods, dts;
  std::optional<int> repeat;
  std::optional<double> seconds;
  std::string output;
  std::string shard;
  std::string record;  // a folder for a recording of every run, "" for none
  bool quiet = false;
  SceneLimits limits;
};

// Runs the sweep into o.output (resuming what it already holds); returns the exit status. Throws
// UsageError for a spec, scene or method it cannot take.
int runSweep(const SweepOptions& o);

}  // namespace substep::app

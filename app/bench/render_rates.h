// substep-render-bench --rates: the video's and the stream's frame rates against the drawing
// alone, in one run (render_rates.cpp says how).
#pragma once

#include "physics/scene_file.h"

#include <memory>
#include <string>
#include <vector>

namespace substep::app {

struct RatesOptions {
  int rounds = 3;
  double seconds = 5;        // of each video [simulated s]
  int fps = 60;              // the video's
  std::string size;          // WIDTHxHEIGHT, passed to `substep render`
  double streamSeconds = 8;  // each live session's run [wall s]
  int streamFps = 30;        // asked of the live session (serve's default)
  bool adaptSize = true;     // the live session lowers its size when the drawing cannot keep up
  bool check = false;        // exit status 1 when a target is not met
  std::string substep;       // the substep program; default: beside this one
};

// Prints each round and the verdicts; 0, or 1 with `check` when a target is not met.
int runRates(const RatesOptions& o, const std::vector<std::shared_ptr<const Scene>>& scenes, int width, int height);

}  // namespace substep::app

// What the timeline of a run marks (the viewer's scrubber, `substep serve`): where each of the
// scene's "pass" bounds first fails as the run goes (the verdict's own check, lab/verdict.h, on the
// metrics of the run so far), and the worst penetration, joint error and speed so far, each with
// its step and body. It reads snapshots in step order, a live panel's or a recording's alike.
#pragma once

#include "lab/metrics.h"
#include "physics/scene_file.h"
#include "physics/snapshot.h"

#include <optional>
#include <string>
#include <vector>

namespace substep::lab {

struct TimelineMarker {
  std::string kind;        // "criterion", "penetration", "joint_error", "speed" (the app adds "diverged")
  long long step = 0;
  double time = 0;         // [s]
  int body = -1;           // the body it is about, -1 when none
  double value = 0;        // the criterion's metric, the depth or error [m], the speed [m/s]
  std::string text;        // "max penetration 3.1 mm > 2 mm", "deepest contact 4.2 mm"
};

class TimelineWatch {
 public:
  // `seconds`: the run's planned length (the metrics of the run's second half need it); a live
  // run with no end: a large number.
  TimelineWatch(const Scene& scene, double seconds);
  void add(const Snapshot& s);  // in step order, from t = 0
  // The first failure of each bound, then the worst of each kind so far (none while zero).
  std::vector<TimelineMarker> markers() const;
  // The worst of a kind ("penetration", "joint_error", "speed"), if any so far.
  std::optional<TimelineMarker> worst(const std::string& kind) const;

 private:
  const Scene& scene_;
  Probe probe_;
  std::vector<std::optional<TimelineMarker>> failed_;  // per bound of scene.criteria->pass
  int open_ = 0;                                        // bounds not failed yet
  std::optional<TimelineMarker> pen_, joint_, speed_;
};

}  // namespace substep::lab

// What the viewer shows of a session besides its frames: the timeline's markers (lab/timeline.h,
// fed by every snapshot the panels keep) and the inspector's account of one body at the shown
// step, both as the API's JSON (docs/server.md). The inspector's numbers are the snapshot's: the
// recording's own when a recording is replayed.
#pragma once

#include "app/server/http.h"
#include "lab/timeline.h"
#include "render/session.h"

#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace substep::app::web {

// The markers of a session's panels, kept up to date by the render session's snapshot hook (on
// the session's thread) and read by requests: hence its own lock.
class SessionTimeline {
 public:
  // `seconds`: the planned length of the runs (a recording's), or 0 for a live session.
  explicit SessionTimeline(double seconds = 0) : seconds_(seconds) {}
  // The hook to give RenderSession::setSnapshotHook.
  render::RenderSession::SnapshotHook hook();
  // Every panel's markers, with the divergences of `r` added; in time order.
  json markersJson(const render::RenderSession& r) const;
  // The worst marker of a kind ("penetration", "joint_error", "speed") of one panel, or of the
  // panel where it is largest (panel < 0).
  std::optional<std::pair<int, lab::TimelineMarker>> worst(const std::string& kind, int panel) const;

 private:
  struct Watch {
    std::shared_ptr<const Scene> scene;  // the watch refers to it
    std::unique_ptr<lab::TimelineWatch> watch;
  };
  double seconds_;
  mutable std::mutex m_;
  std::vector<Watch> panels_;
};

// A marker of panel `panel` as the API gives it (the body by name).
json markerJson(int panel, const lab::TimelineMarker& m, const Model& model);
// The timeline's span and cursor: first, last, shown, shown_step, live, recorded, dt.
json timelineJson(const render::RenderSession& r);
// Body `body` of every panel at its shown step (docs/server.md, the inspector); body < 0: none.
json inspectJson(const render::RenderSession& r, const std::vector<std::string>& methods, int body);

}  // namespace substep::app::web

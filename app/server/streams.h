// The two streams of a session of `substep serve`: the frames as MJPEG (an <img> shows it) and
// the stats as server-sent events (the page's plots). Each holds one of httplib's threads while
// it lives, and ends when the session closes or the server stops.
#pragma once

#include "app/server/http.h"
#include "app/server/sessions.h"

#include <memory>

namespace substep::app::web {

constexpr int kMaxViewers = 4;  // streams of one session at once

// Answers with the session's frames; HttpError 503 when it has kMaxViewers already.
void streamMjpeg(Response& res, const std::shared_ptr<WebSession>& s, const Sessions& sessions);
// Answers with the session's stats, at most 15 a second; keeps the session from expiring.
void streamEvents(Response& res, const std::shared_ptr<WebSession>& s, const Sessions& sessions);

}  // namespace substep::app::web

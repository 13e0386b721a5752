// The JSON of `substep serve`'s answers (docs/server.md): what a session's state, its stats, a
// clip, a pick, the scenes, the methods and the server look like to the page. One place for each,
// so that the calls that answer the same thing answer it alike.
#pragma once

#include "app/server.h"
#include "app/server/sessions.h"
#include "render/live_session.h"

#include <nlohmann/json.hpp>

#include <string>

namespace substep::app::web {

using json = nlohmann::json;

json vec(const Vec3& v);
// GET /api/methods: the algorithms with their defaults, the settings schema (physics/settings_json.h),
// the colour modes.
json methodsJson();
// An entry of GET /api/scenes.
json sceneJson(const std::string& name, const Scene& s);
// GET /api/server: the sessions open and the limits.
json serverJson(const ServerOptions& o, size_t sessions, bool clips, bool lab);

// A session's state, as GET /api/sessions/S and every call that changes it answer; takes the
// session's lock.
json stateJson(WebSession& s);
json statsJson(const render::LiveStats& s);
json clipJson(const render::ClipInfo& c, const std::string& sessionId);
json pickJson(const render::RenderSession::Pick& p, const Scene& sc);

}  // namespace substep::app::web

// The routes of `substep serve`: which method and path reach which handler, in the order httplib
// tries them (the first pattern that matches answers). docs/server.md lists the same calls.
#include "app/server/api_json.h"
#include "app/server/handlers.h"

namespace substep::app::web {

void addRoutes(Router& router, Handlers& h) {
  using H = Handlers;
  // A call answered by its handler.
  const auto answer = [&h](void (H::*call)(const Request&, Response&)) -> Router::Handler {
    return [&h, call](const Request& req, Response& res) { (h.*call)(req, res); };
  };
  // A change of the session the path names, answered with the session's state.
  const auto change = [&h](void (H::*call)(WebSession&, const Request&)) -> Router::Handler {
    return [&h, call](const Request& req, Response& res) {
      const auto s = h.session(req);
      (h.*call)(*s, req);
      sendJson(res, stateJson(*s));
    };
  };
  const std::string sid = R"(/api/sessions/([0-9a-f]{16}))";
  const std::string anyId = R"(/api/sessions/([^/]+))";
  const struct {
    const char* method;
    std::string pattern;
    Router::Handler handler;
  } routes[] = {
      {"GET", "/api/scenes", answer(&H::scenes)},
      {"GET", "/api/methods", answer(&H::methods)},
      {"GET", "/api/server", answer(&H::server)},
      {"GET", "/api/lab", answer(&H::lab)},

      {"GET", "/api/recordings", answer(&H::recordings)},
      {"POST", "/api/recordings", answer(&H::uploadRecording)},

      {"POST", "/api/sessions", answer(&H::create)},
      {"GET", sid, answer(&H::state)},
      {"DELETE", sid, answer(&H::close)},
      {"POST", sid + "/close", answer(&H::close)},  // what a closing page can send (navigator.sendBeacon posts)

      {"POST", sid + "/settings", change(&H::settings)},
      {"POST", sid + "/panels", change(&H::panels)},
      {"POST", sid + "/scene", change(&H::scene)},
      {"POST", sid + "/camera", change(&H::camera)},
      {"POST", sid + "/view", change(&H::view)},
      {"POST", sid + "/play", change(&H::play)},
      {"POST", sid + "/pause", change(&H::pause)},
      {"POST", sid + "/step", change(&H::step)},
      {"POST", sid + "/reset", change(&H::reset)},
      {"POST", sid + "/seek", change(&H::seek)},
      {"POST", sid + "/scrub", change(&H::scrub)},
      {"GET", sid + "/timeline", answer(&H::timeline)},
      {"POST", sid + "/select", answer(&H::select)},
      {"GET", sid + "/inspect", answer(&H::inspect)},
      {"POST", sid + "/worst", answer(&H::worst)},
      {"POST", sid + "/pick", answer(&H::pick)},
      {"POST", sid + "/push", answer(&H::push)},

      {"GET", sid + "/stats", answer(&H::stats)},
      {"GET", sid + R"(/frame\.png)", answer(&H::frame)},
      {"GET", sid + R"(/stream\.mjpeg)", answer(&H::stream)},
      {"GET", sid + "/events", answer(&H::events)},

      {"POST", sid + "/clips", answer(&H::record)},
      {"GET", sid + "/clips", answer(&H::clips)},
      {"GET", sid + R"(/clips/([0-9]+))", answer(&H::clip)},
      {"GET", sid + R"(/clips/([0-9]+)\.mp4)", answer(&H::clipVideo)},

      // Unknown sessions of any shape are 404 too (a well-formed id that is open is answered
      // above); an open session's unknown path is the usual 404 or 405.
      {"GET", anyId + "(/.*)?", answer(&H::noSession)},
      {"POST", anyId + "(/.*)?", answer(&H::noSession)},
      {"DELETE", anyId + "(/.*)?", answer(&H::noSession)},

      {"GET", R"(/lab/(.+))", answer(&H::labFile)},
      {"GET", "/", answer(&H::page)},
      {"GET", R"(/(.+))", answer(&H::webFile)},
  };
  for (const auto& r : routes) router.add(r.method, r.pattern, r.handler);
}

}  // namespace substep::app::web

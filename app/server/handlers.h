// The calls of `substep serve` (docs/server.md), one function each: read the request (Fields,
// requests.h), act on the session or the registry, answer with the JSON of api_json.h. The
// routes (routes.cpp) say which path and method reach which.
#pragma once

#include "app/server.h"
#include "app/server/http.h"
#include "app/server/sessions.h"

#include <memory>

namespace substep::app::web {

class Handlers {
 public:
  Handlers(const ServerOptions& o, Sessions& sessions, const Router& router)
      : o_(o), sessions_(sessions), router_(router) {}

  // The session that matches[1] of the path names; HttpError 404 if none.
  std::shared_ptr<WebSession> session(const Request& req);

  // Scenes, methods, the server, the lab.
  void scenes(const Request&, Response& res);
  void methods(const Request&, Response& res);
  void server(const Request&, Response& res);
  void lab(const Request&, Response& res);

  // Recordings: those the server can open, an upload.
  void recordings(const Request& req, Response& res);
  void uploadRecording(const Request& req, Response& res);

  // Sessions.
  void create(const Request& req, Response& res);
  void state(const Request& req, Response& res);
  void close(const Request& req, Response& res);
  // Any other path under an id: 404 naming the id when no session has it, else 404 or 405.
  void noSession(const Request& req, Response& res);

  // Changes of a session, answered with its state (routes.cpp).
  void settings(WebSession& s, const Request& req);
  void panels(WebSession& s, const Request& req);
  void scene(WebSession& s, const Request& req);
  void camera(WebSession& s, const Request& req);
  void view(WebSession& s, const Request& req);
  void play(WebSession& s, const Request& req);
  void pause(WebSession& s, const Request& req);
  void step(WebSession& s, const Request& req);
  void reset(WebSession& s, const Request& req);
  void seek(WebSession& s, const Request& req);
  void scrub(WebSession& s, const Request& req);

  // The timeline, the inspector.
  void timeline(const Request& req, Response& res);
  void select(const Request& req, Response& res);
  void inspect(const Request& req, Response& res);
  void worst(const Request& req, Response& res);

  // Picking and pushing, answered with what the ray hit.
  void pick(const Request& req, Response& res);
  void push(const Request& req, Response& res);

  // Stats, the frame, the streams.
  void stats(const Request& req, Response& res);
  void frame(const Request& req, Response& res);
  void stream(const Request& req, Response& res);
  void events(const Request& req, Response& res);

  // Clips.
  void record(const Request& req, Response& res);
  void clips(const Request& req, Response& res);
  void clip(const Request& req, Response& res);
  void clipVideo(const Request& req, Response& res);

  // Files: the lab's under /lab/, the page's under /.
  void labFile(const Request& req, Response& res);
  void page(const Request&, Response& res);
  void webFile(const Request& req, Response& res);

 private:
  // The clip that matches[2] of the path numbers, of the session `s` is set to.
  render::ClipInfo clipOf(const Request& req, std::shared_ptr<WebSession>& s);
  // POST /api/sessions with "recording" or "recordings": a recorded session.
  void createRecorded(const Fields& f, Response& res);
  json labFiles() const;

  const ServerOptions& o_;
  Sessions& sessions_;
  const Router& router_;
};

// Every call's method and path to its handler (routes.cpp).
void addRoutes(Router& router, Handlers& h);

}  // namespace substep::app::web

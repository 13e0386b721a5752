// The calls of `substep serve`: see handlers.h. What a body may hold is read in requests.cpp and
// what an answer looks like is in api_json.cpp; here, only what each call does.
#include "app/server/handlers.h"

#include "app/common.h"
#include "app/server/api_json.h"
#include "app/server/requests.h"
#include "app/server/streams.h"
#include "render/image.h"

#include <algorithm>
#include <filesystem>
#include <sstream>

namespace substep::app::web {

namespace fs = std::filesystem;
using namespace substep::render;

namespace {

// A change that starts the panels again; a panel that cannot start is a 400 naming it.
template <class F>
void restart(WebSession& s, const std::string& field, F&& change) {
  try {
    s.live->restart(std::forward<F>(change));
  } catch (const PanelError& e) {
    throw HttpError(400, field + "panel " + std::to_string(e.panel) + ": " + e.what());
  }
}

// The camera preset of the scene a request names ("fitted": one fitted to panel 0's bodies now).
std::optional<CameraPreset> presetOf(WebSession& s, const std::optional<std::string>& name) {
  if (!name) return std::nullopt;
  const Scene& sc = *s.scene;
  if (*name == "fitted")
    return s.live->read([&](const RenderSession& r, const Look&) { return fittedCamera(sc.model, r.panel(0).state()); });
  for (const CameraPreset& c : sc.cameras)
    if (c.name == *name) return c;
  std::vector<std::string> names;
  for (const CameraPreset& c : sc.cameras) names.push_back(c.name);
  names.push_back("fitted");
  throw HttpError(400, "preset: expected one of " + joined(names) + ", got " + quote(json(*name)));
}

// A given impulse on a named body (at its centre, or at "point"), in every panel.
json pushBody(WebSession& s, const Fields& f) {
  if (f.has("x") || f.has("y") || f.has("speed")) throw HttpError(400, "body: give body and impulse, or x and y, not both");
  const Model& model = s.scene->model;
  const std::string name = f.text("body", limits::kMaxNameLength);
  const int b = model.bodyIndex(name);
  if (b < 0 || model.bodies[static_cast<size_t>(b)].isStatic)
    throw HttpError(400, "body: expected the name of a dynamic body of " + s.sceneName + ", got " + quote(json(name)));
  if (!f.has("impulse")) throw HttpError(400, "impulse: expected [x, y, z] in N s");
  const Vec3 impulse = f.vec3("impulse", {-1e9, 1e9});
  std::optional<Vec3> point;
  if (f.has("point")) point = f.vec3("point", limits::kCoordinate);
  return s.live->change([&](RenderSession& r, Look&) {
    const Vec3 p = point ? *point : r.panel(0).state().bodies[static_cast<size_t>(b)].x;
    r.push(0, b, impulse, p);
    return json{{"hit", true}, {"panel", 0}, {"body", b}, {"name", name}, {"point", vec(p)}, {"impulse", vec(impulse)}};
  });
}

// The body under a pixel pushed along the view ray at "speed" (a mass-independent feel).
json pushAtPixel(WebSession& s, const Fields& f) {
  const int w = s.live->config().width, h = s.live->config().height;
  const auto xy = pixel(f, w, h);
  const double speed = f.has("speed") ? f.number("speed", {0, 100, true}) : 3.0;
  return s.live->change([&](RenderSession& r, Look&) {
    const RenderSession::Pick p = r.pick(w, h, xy.first, xy.second);
    json j = pickJson(p, *s.scene);
    if (p.hit.body < 0) return j;
    const Vec3 impulse = s.scene->model.bodies[static_cast<size_t>(p.hit.body)].mass * speed * p.direction;
    r.push(p.panel, p.hit.body, impulse, p.hit.point);
    j["impulse"] = vec(impulse);
    return j;
  });
}

}  // namespace

std::shared_ptr<WebSession> Handlers::session(const Request& req) { return sessions_.find(req.matches[1]); }

// --- scenes, methods, the server, the lab ---

void Handlers::scenes(const Request&, Response& res) {
  json list = json::array();
  for (const std::string& name : sessions_.sceneNames()) {
    try {
      list.push_back(sceneJson(name, *sessions_.scene(name, "scene")));
    } catch (const HttpError& e) {
      list.push_back({{"name", name}, {"error", e.what()}});
    }
  }
  sendJson(res, {{"scenes", list}});
}

void Handlers::methods(const Request&, Response& res) { sendJson(res, methodsJson()); }

void Handlers::server(const Request&, Response& res) {
  sendJson(res, serverJson(o_, sessions_.count(), sessions_.canRecord(), !labFiles().empty()));
}

void Handlers::lab(const Request&, Response& res) { sendJson(res, {{"files", labFiles()}}); }

// --- sessions ---

void Handlers::create(const Request& req, Response& res) {
  const Fields f(req, {"scene", "method", "methods", "size", "fps", "play", "speed", "recording", "recordings", "focus"});
  if (f.has("recording") || f.has("recordings")) {
    for (const char* k : {"scene", "method", "methods", "play", "speed", "fps"})
      if (f.has(k)) throw HttpError(400, std::string(k) + ": a recorded session replays its recordings; give only recording(s), size and focus");
    return createRecorded(f, res);
  }
  if (f.has("focus")) throw HttpError(400, "focus: only with recording or recordings");
  auto s = std::make_shared<WebSession>();
  s->sceneName = sceneName(f);
  s->scene = sessions_.scene(s->sceneName, "scene");
  s->panels = newPanels(f);
  LiveConfig c = sessions_.config();
  if (f.has("size")) frameSize(f, c.width, c.height);
  if (f.has("fps")) c.fps = f.integer("fps", {1, 60});
  const double speed = f.has("speed") ? f.number("speed", {0.01, 10}) : 1.0;
  const bool play = f.has("play") && f.flag("play");
  Look look;
  look.camera = chooseCamera(*s->scene, {});
  look.stepCost = true;
  s->timeline = std::make_shared<SessionTimeline>();
  sessions_.open(s, setups(*s->scene, s->panels, o_.sleep), look, c, play ? std::optional<double>(speed) : std::nullopt);
  sendJson(res, stateJson(*s), 201);
}

void Handlers::state(const Request& req, Response& res) { sendJson(res, stateJson(*session(req))); }

void Handlers::close(const Request& req, Response& res) {
  const auto s = session(req);
  sessions_.remove(s->id, "closed by request");
  sendJson(res, {{"closed", s->id}});
}

void Handlers::noSession(const Request& req, Response& res) {
  const std::string id = req.matches[1];
  if (sessions_.isOpen(id)) return router_.notFound(req, res);
  throw sessions_.noSuchSession(id);
}

// --- changes of a session ---

void Handlers::settings(WebSession& s, const Request& req) {
  const Fields f(req, {"panel", "method", "settings"});
  std::lock_guard<std::mutex> lk(s.m);
  const std::vector<int> targets = panelTargets(f, static_cast<int>(s.panels.size()));
  std::vector<WebSession::PanelState> next = s.panels;
  for (int i : targets) {
    SolverOverrides& u = next[static_cast<size_t>(i)].user;
    if (f.has("method")) u = methodOverrides(f.text("method"), "method");
    if (f.has("settings")) changeSettings(u, f.at("settings"));
  }
  if (!f.has("method") && !f.has("settings")) throw HttpError(400, "method, settings: give a method or settings to change");
  const std::vector<PanelSetup> ps = setups(*s.scene, next, o_.sleep);  // every panel checked before any changes
  try {
    s.live->change([&](RenderSession& r, Look&) {
      for (int i : targets) r.setSettings(i, ps[static_cast<size_t>(i)].settings);
    });
  } catch (const std::invalid_argument& e) {  // the past or a recording, which cannot change
    throw HttpError(409, e.what());
  }
  s.panels = std::move(next);
}

void Handlers::panels(WebSession& s, const Request& req) {
  const Fields f(req, {"methods"});
  if (!f.has("methods")) throw HttpError(400, "methods: expected 1 to 4 methods, e.g. \"a2:m=4,a5:n=4\"");
  std::lock_guard<std::mutex> lk(s.m);
  std::vector<WebSession::PanelState> next = panelsOf(f.at("methods"), "methods");
  const std::vector<PanelSetup> ps = setups(*s.scene, next, o_.sleep);
  restart(s, "methods: ", [&](RenderSession& r, Look&) { r.setPanels(ps); });
  s.panels = std::move(next);
}

void Handlers::scene(WebSession& s, const Request& req) {
  const Fields f(req, {"scene", "methods"});
  const std::string name = sceneName(f);
  const std::shared_ptr<const Scene> sc = sessions_.scene(name, "scene");
  std::lock_guard<std::mutex> lk(s.m);
  // Without methods, as many panels, each with the new scene's own settings.
  std::vector<WebSession::PanelState> next =
      f.has("methods") ? panelsOf(f.at("methods"), "methods") : std::vector<WebSession::PanelState>(s.panels.size());
  const std::vector<PanelSetup> ps = setups(*sc, next, o_.sleep);
  restart(s, "", [&](RenderSession& r, Look& look) {
    r.setScene(sc, ps);
    look.camera = chooseCamera(*sc, {});
    look.orbit = 0;
    look.view.highlight.clear();
  });
  s.scene = sc;
  s.sceneName = name;
  s.panels = std::move(next);
}

void Handlers::camera(WebSession& s, const Request& req) {
  const CameraChange change{Fields(req, CameraChange::kFields)};
  const int height = s.live->config().height;
  std::lock_guard<std::mutex> lk(s.m);
  change.checkFollow(*s.scene, s.sceneName);
  const std::optional<CameraPreset> chosen = presetOf(s, change.preset);
  s.live->change([&](RenderSession& r, Look& look) { change.apply(look, chosen, s.scene->model, r.panel(0).state(), height); });
}

void Handlers::view(WebSession& s, const Request& req) {
  const Fields f(req, ViewChange::kFields);
  ViewChange change(f);
  std::lock_guard<std::mutex> lk(s.m);
  change.readHighlight(f, *s.scene, s.sceneName);
  s.live->change([&](RenderSession&, Look& look) { change.apply(look); });
}

void Handlers::play(WebSession& s, const Request& req) {
  const Fields f(req, {"speed"});
  double speed = s.live->stats().speed;
  if (f.has("speed")) {
    speed = f.number("speed", {-10, 10});
    if (std::abs(speed) < 0.01)
      throw HttpError(400, "speed: expected 0.01 to 10 simulated seconds per second (negative: backwards), got " +
                               numberText(speed));
  }
  s.live->play(speed);
}

void Handlers::pause(WebSession& s, const Request& req) {
  const Fields f(req, {});
  s.live->pause();
}

void Handlers::step(WebSession& s, const Request& req) {
  const Fields f(req, {"count"});
  const int count = f.has("count") ? f.integer("count", {-kMaxSteps, kMaxSteps}) : 1;
  if (count == 0) throw HttpError(400, "count: expected 1 to " + std::to_string(kMaxSteps) + " steps, negative to go back");
  s.live->step(count);
}

void Handlers::reset(WebSession& s, const Request& req) {
  const Fields f(req, {});
  s.live->reset();
}

void Handlers::seek(WebSession& s, const Request& req) {
  const Fields f(req, {"time"});
  if (!f.has("time")) throw HttpError(400, "time: expected a number in [0, " + numberText(kMaxSeek) + "]");
  s.live->seek(f.number("time", {0, kMaxSeek}));
}

void Handlers::scrub(WebSession& s, const Request& req) {
  const Fields f(req, {"time", "step", "by", "live"});
  const int given = f.has("time") + f.has("step") + f.has("by") + f.has("live");
  if (given != 1)
    throw HttpError(400, "time, step, by, live: give one (a time in s, a kept step of panel 0, a number of kept steps, or live: true)");
  if (f.has("time")) {
    s.live->seek(f.number("time", {0, kMaxSeek}));
  } else if (f.has("step")) {
    const long long k = f.integer("step", {0, 1000000000});
    // Panel 0's kept step k, by its number (a recording thinned by --every keeps only some).
    const std::optional<double> t = s.live->read([&](const RenderSession& r, const Look&) -> std::optional<double> {
      const auto& h = r.panel(0).history();
      const auto it = std::lower_bound(h.begin(), h.end(), k, [](const Snapshot& x, long long n) { return x.state.step < n; });
      if (it == h.end() || it->state.step != k) return std::nullopt;
      return it->state.time;
    });
    if (!t) {
      const json tl = s.live->read([](const RenderSession& r, const Look&) { return timelineJson(r); });
      throw HttpError(409, "step " + std::to_string(k) + " is not kept (the timeline keeps t = " + numberText(tl["first"].get<double>()) +
                               " to " + numberText(tl["last"].get<double>()) + " s; a recording made with --every keeps every K-th step)");
    }
    s.live->seek(*t);
  } else if (f.has("by")) {
    s.live->step(f.integer("by", {-1000000000, 1000000000}));
  } else {
    if (!f.flag("live")) throw HttpError(400, "live: expected true (to show the newest step)");
    s.live->live();
  }
}

// --- the timeline and the inspector ---

namespace {

std::vector<std::string> methodsOf(const WebSession& s) {
  std::vector<std::string> m;
  for (const auto& p : s.panels) m.push_back(p.method());
  return m;
}

// Selects body b (-1: none), highlighted in every panel; answers the inspector. Under s.m.
json selectBody(WebSession& s, int b) {
  s.selected = b;
  return s.live->change([&](RenderSession& r, Look& look) {
    look.view.highlight.clear();
    if (b >= 0) look.view.highlight.push_back(s.scene->model.bodies[static_cast<size_t>(b)].name);
    return inspectJson(r, methodsOf(s), b);
  });
}

int bodyNamed(const WebSession& s, const std::string& name, const std::string& field) {
  const int b = s.scene->model.bodyIndex(name);
  if (b < 0) throw HttpError(400, field + ": expected the name of a body of " + s.sceneName + ", got " + quote(json(name)));
  return b;
}

}  // namespace

// Where a recorded session opens when asked to focus on panel k (an atlas cell): its first failure
// (a criterion's or a divergence), else its worst of the scene's error measure; none: t = 0.
std::optional<std::pair<double, std::string>> focusOf(const WebSession& s, int panel) {
  const json markers = s.live->read([&](const RenderSession& r, const Look&) { return s.timeline->markersJson(r); });
  for (const json& m : markers)
    if (m["panel"] == panel && (m["kind"] == "criterion" || m["kind"] == "diverged"))
      return std::make_pair(m["time"].get<double>(), m["body"].is_string() ? m["body"].get<std::string>() : "");
  const std::string kind = s.scene->model.joints.empty() ? "penetration" : "joint_error";
  for (const std::string& k : {kind, std::string("penetration"), std::string("speed")})
    if (const auto w = s.timeline->worst(k, panel))
      return std::make_pair(w->second.time,
                            w->second.body >= 0 ? s.scene->model.bodies[static_cast<size_t>(w->second.body)].name : "");
  return std::nullopt;
}

void Handlers::recordings(const Request&, Response& res) {
  json list = json::array();
  for (const Sessions::KnownRecording& k : sessions_.recordings()) list.push_back({{"name", k.name}, {"bytes", k.bytes}});
  sendJson(res, {{"recordings", list}});
}

void Handlers::uploadRecording(const Request& req, Response& res) {
  if (req.body.empty()) throw HttpError(400, "body: expected the bytes of a recording (.rec), got none");
  const std::string name = sessions_.upload(req.body, req.has_param("name") ? req.get_param_value("name") : "upload.rec");
  sendJson(res, {{"name", name}}, 201);
}

void Handlers::createRecorded(const Fields& f, Response& res) {
  std::vector<std::string> names;
  if (f.has("recording") && f.has("recordings")) throw HttpError(400, "recording: give recording or recordings, not both");
  if (f.has("recording")) names.push_back(f.text("recording", 600));
  if (f.has("recordings")) {
    const json& v = f.at("recordings");
    if (v.is_string()) {
      std::string list = v.get<std::string>(), item;
      std::stringstream ss(list);
      while (std::getline(ss, item, ',')) names.push_back(item);
    } else if (v.is_array()) {
      for (const json& x : v) {
        if (!x.is_string()) throw HttpError(400, "recordings: expected names (strings), got " + quote(x));
        names.push_back(x.get<std::string>());
      }
    } else {
      throw HttpError(400, "recordings: expected a list of names, or names separated by commas");
    }
  }
  if (names.empty() || static_cast<int>(names.size()) > kMaxPanels)
    throw HttpError(400, "recordings: expected 1 to " + std::to_string(kMaxPanels) + " recordings");
  // The panels of every recording, side by side on one timeline: of one scene.
  auto s = std::make_shared<WebSession>();
  std::vector<PanelSetup> setups;
  std::vector<std::vector<Snapshot>> frames;
  double seconds = 0;
  for (const std::string& n : names) {
    const auto r = sessions_.recording(n, "recording");
    if (!s->scene) {
      s->scene = r->scene;
    } else if (r->scene->text != s->scene->text) {
      throw HttpError(400, "recordings: " + n + " is of another scene than " + names.front() + "; side by side, recordings share a scene");
    }
    for (size_t i = 0; i < r->panels.size(); ++i) {
      setups.push_back(r->panels[i]);
      frames.push_back(r->frames[i]);
      WebSession::PanelState ps;
      ps.recorded = r->panels[i].name.empty() ? fs::path(n).stem().string() : r->panels[i].name;
      setups.back().name = ps.recorded;
      s->panels.push_back(ps);
    }
    seconds = std::max(seconds, r->seconds);
  }
  if (static_cast<int>(setups.size()) > kMaxPanels)
    throw HttpError(400, "recordings: " + std::to_string(setups.size()) + " panels in all; at most " + std::to_string(kMaxPanels));
  if (setups.size() == 1) setups[0].name.clear();
  s->sceneName = fs::path(names.front()).stem().string();
  s->timeline = std::make_shared<SessionTimeline>(seconds);
  LiveConfig c = sessions_.config();
  if (f.has("size")) frameSize(f, c.width, c.height);
  Look look;
  look.camera = chooseCamera(*s->scene, {});
  const auto scene = s->scene;
  sessions_.open(s, setups, look, c, std::nullopt,
                 [&](RenderSession& r, Look&) { r.setRecorded(scene, setups, std::move(frames)); });
  if (f.has("focus")) {
    const int panel = f.integer("focus", {0, static_cast<double>(setups.size()) - 1});
    std::lock_guard<std::mutex> lk(s->m);
    if (const auto at = focusOf(*s, panel)) {
      s->live->seek(at->first);
      if (!at->second.empty()) selectBody(*s, s->scene->model.bodyIndex(at->second));
    }
  }
  sendJson(res, stateJson(*s), 201);
}

void Handlers::timeline(const Request& req, Response& res) {
  const auto s = session(req);
  std::lock_guard<std::mutex> lk(s->m);
  sendJson(res, s->live->read([&](const RenderSession& r, const Look&) {
    json j = timelineJson(r);
    j["markers"] = s->timeline->markersJson(r);
    return j;
  }));
}

void Handlers::select(const Request& req, Response& res) {
  const auto s = session(req);
  const Fields f(req, {"x", "y", "body"});
  std::lock_guard<std::mutex> lk(s->m);
  if (f.has("body")) {
    if (f.has("x") || f.has("y")) throw HttpError(400, "body: give a body, or x and y, not both");
    if (f.at("body").is_null()) return sendJson(res, selectBody(*s, -1));
    return sendJson(res, selectBody(*s, bodyNamed(*s, f.text("body", limits::kMaxNameLength), "body")));
  }
  const int w = s->live->config().width, h = s->live->config().height;
  const auto xy = pixel(f, w, h);
  const RenderSession::Pick p =
      s->live->read([&](const RenderSession& r, const Look&) { return r.pick(w, h, xy.first, xy.second); });
  json j = selectBody(*s, p.hit.body);
  j["pick"] = pickJson(p, *s->scene);
  sendJson(res, j);
}

void Handlers::inspect(const Request& req, Response& res) {
  const auto s = session(req);
  std::lock_guard<std::mutex> lk(s->m);
  int b = s->selected;
  if (req.has_param("body")) b = bodyNamed(*s, req.get_param_value("body").substr(0, limits::kMaxNameLength), "body");
  sendJson(res, s->live->read([&](const RenderSession& r, const Look&) { return inspectJson(r, methodsOf(*s), b); }));
}

void Handlers::worst(const Request& req, Response& res) {
  const auto s = session(req);
  const Fields f(req, {"kind", "panel"});
  const std::string kind = f.has("kind") ? f.text("kind", 20) : "penetration";
  if (kind != "penetration" && kind != "joint_error" && kind != "speed")
    throw HttpError(400, "kind: expected penetration, joint_error or speed, got " + quote(json(kind)));
  std::lock_guard<std::mutex> lk(s->m);
  const int panel = f.has("panel") ? f.integer("panel", {0, static_cast<double>(s->panels.size()) - 1}) : -1;
  const auto w = s->timeline->worst(kind, panel);
  if (!w) throw HttpError(409, "no " + kind + " so far" + (panel >= 0 ? " in panel " + std::to_string(panel) : "") +
                                   ": play the scene first");
  s->live->seek(w->second.time);
  json j;
  j["marker"] = markerJson(w->first, w->second, s->scene->model);
  j["inspect"] = selectBody(*s, w->second.body);
  sendJson(res, j);
}

// --- picking and pushing ---

void Handlers::pick(const Request& req, Response& res) {
  const auto s = session(req);
  const Fields f(req, {"x", "y"});
  const int w = s->live->config().width, h = s->live->config().height;
  const auto xy = pixel(f, w, h);
  std::lock_guard<std::mutex> lk(s->m);
  sendJson(res, pickJson(s->live->read([&](const RenderSession& r, const Look&) { return r.pick(w, h, xy.first, xy.second); }),
                         *s->scene));
}

void Handlers::push(const Request& req, Response& res) {
  const auto s = session(req);
  const Fields f(req, {"x", "y", "speed", "body", "impulse", "point"});
  try {
    std::lock_guard<std::mutex> lk(s->m);
    sendJson(res, f.has("body") ? pushBody(*s, f) : pushAtPixel(*s, f));
  } catch (const std::invalid_argument& e) {  // World::applyImpulse; the past or a recording (409)
    const bool past = std::string(e.what()).find("go live first") != std::string::npos ||
                      std::string(e.what()).find("recording") != std::string::npos;
    throw HttpError(past ? 409 : 400, e.what());
  }
}

// --- stats, the frame, the streams ---

void Handlers::stats(const Request& req, Response& res) { sendJson(res, statsJson(session(req)->live->stats())); }

void Handlers::frame(const Request& req, Response& res) {
  const auto s = session(req);
  const std::shared_ptr<const Image> img = s->live->image(10.0);
  if (!img) {
    const std::string why = s->live->stats().status;
    throw HttpError(503, "no frame could be drawn" + (why.empty() ? std::string(" in 10 s") : ": " + why));
  }
  const std::vector<uint8_t> png = encodePng(*img);
  const LiveStats st = s->live->stats();
  char name[96];
  std::snprintf(name, sizeof name, "substep-%s-%.2fs.png", s->sceneName.c_str(), st.panels.empty() ? 0.0 : st.panels[0].time);
  res.set_header("Content-Disposition", std::string("attachment; filename=\"") + name + "\"");
  res.set_header("Cache-Control", "no-store");
  res.set_content(std::string(png.begin(), png.end()), "image/png");
}

void Handlers::stream(const Request& req, Response& res) { streamMjpeg(res, session(req), sessions_); }

void Handlers::events(const Request& req, Response& res) { streamEvents(res, session(req), sessions_); }

// --- clips ---

void Handlers::record(const Request& req, Response& res) {
  const auto s = session(req);
  const Fields f(req, {"mode", "seconds"});
  const std::string mode = f.has("mode") ? f.text("mode", 20) : "last";
  if (mode != "last" && mode != "next") throw HttpError(400, "mode: expected last or next, got " + quote(f.at("mode")));
  const double seconds = f.has("seconds") ? f.number("seconds", {0.1, mode == "last" ? o_.history : 60.0}) : 5.0;
  if (!sessions_.canRecord())
    throw HttpError(503, "clips need the ffmpeg program, which is not on PATH (Debian: apt-get install ffmpeg)");
  int id;
  try {
    id = s->live->record(mode, seconds);
  } catch (const std::invalid_argument& e) {
    throw HttpError(409, e.what());
  }
  sendJson(res, clipJson(*s->live->clip(id), s->id), 202);
}

void Handlers::clips(const Request& req, Response& res) {
  const auto s = session(req);
  json list = json::array();
  for (const ClipInfo& c : s->live->clips()) list.push_back(clipJson(c, s->id));
  sendJson(res, {{"clips", list}});
}

ClipInfo Handlers::clipOf(const Request& req, std::shared_ptr<WebSession>& s) {
  s = session(req);
  const std::string n = req.matches[2];
  const std::optional<ClipInfo> c = n.size() < 9 ? s->live->clip(std::stoi(n)) : std::nullopt;
  if (!c) throw HttpError(404, "session " + s->id + " has no clip " + n.substr(0, 20));
  return *c;
}

void Handlers::clip(const Request& req, Response& res) {
  std::shared_ptr<WebSession> s;
  const ClipInfo c = clipOf(req, s);
  sendJson(res, clipJson(c, s->id));
}

void Handlers::clipVideo(const Request& req, Response& res) {
  std::shared_ptr<WebSession> s;
  const ClipInfo c = clipOf(req, s);
  if (c.state != "done")
    throw HttpError(409, "clip " + std::to_string(c.id) + " is " + c.state + (c.error.empty() ? "" : ": " + c.error));
  serveFile(s->clipFolder, fs::path(c.path).filename().string(), res);
  res.set_header("Content-Disposition",
                 "attachment; filename=\"substep-" + s->sceneName + "-clip" + std::to_string(c.id) + ".mp4\"");
}

// --- files ---

json Handlers::labFiles() const {
  json files = json::array();
  if (o_.labDir.empty()) return files;
  std::error_code ec;
  std::vector<std::string> names;
  for (auto it = fs::recursive_directory_iterator(o_.labDir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    const std::string rel = fs::relative(it->path(), o_.labDir, ec).string();
    const std::string ext = it->path().extension().string();
    if ((ext == ".html" || ext == ".svg" || ext == ".png") && !staticFile(o_.labDir, rel).empty()) names.push_back(rel);
    if (names.size() >= 500) break;
  }
  std::sort(names.begin(), names.end());
  for (const auto& n : names) files.push_back({{"name", n}, {"url", "/lab/" + n}});
  return files;
}

void Handlers::labFile(const Request& req, Response& res) {
  if (o_.labDir.empty()) throw HttpError(404, "no lab folder (substep serve --lab DIR)");
  serveFile(o_.labDir, req.matches[1], res);
}

void Handlers::page(const Request&, Response& res) { serveFile(o_.webRoot, "index.html", res); }

void Handlers::webFile(const Request& req, Response& res) {
  const std::string rel = req.matches[1];
  if (rel.compare(0, 4, "api/") == 0) return router_.notFound(req, res);
  serveFile(o_.webRoot, rel, res);
}

}  // namespace substep::app::web

#include "app/server.h"

#include "app/common.h"
#include "app/render_options.h"
#include "render/compare.h"
#include "render/live_session.h"
#include "render/video.h"

#include <httplib.h>
#include <nlohmann/json.hpp>

#include <malloc.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <mutex>
#include <random>
#include <regex>
#include <sstream>
#include <thread>

namespace substep::app {

namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using httplib::Request;
using httplib::Response;
using namespace substep::render;

constexpr int kMaxPanels = 4;
constexpr int kMaxViewers = 4;       // streams of one session at once
constexpr int kMaxWidth = 1920, kMaxHeight = 1080, kMinSide = 64;
constexpr double kMaxSeek = 3600;    // [s] simulated
constexpr int kMaxSteps = 600;       // one request's single steps

// A request that cannot be answered as asked: the status and the message of the JSON answer.
struct HttpError : std::runtime_error {
  HttpError(int status, const std::string& message) : std::runtime_error(message), status(status) {}
  int status;
};

std::string quote(const json& v) {
  std::string s = v.dump();
  if (s.size() > limits::kMaxMessageValue) s = s.substr(0, limits::kMaxMessageValue) + "...";
  return s;
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

// The fields of a JSON request body, each checked where it is read; unknown fields are refused,
// so that a misspelt one is not silently ignored.
class Fields {
 public:
  Fields(const Request& req, const std::vector<std::string>& allowed) {
    if (req.body.find_first_not_of(" \t\r\n") == std::string::npos) {
      j_ = json::object();
    } else {
      try {
        j_ = json::parse(req.body);
      } catch (const json::exception& e) {
        throw HttpError(400, std::string("body: expected a JSON object: ") + e.what());
      }
      if (!j_.is_object()) throw HttpError(400, "body: expected a JSON object, got " + quote(j_));
    }
    for (const auto& [k, v] : j_.items())
      if (std::find(allowed.begin(), allowed.end(), k) == allowed.end())
        throw HttpError(400, "unknown field \"" + k.substr(0, limits::kMaxMessageValue) + "\"; expected " +
                                 (allowed.empty() ? std::string("none") : "one of " + joined(allowed)));
  }

  bool has(const std::string& k) const { return j_.contains(k) && !j_.at(k).is_null(); }
  const json& at(const std::string& k) const { return j_.at(k); }

  double number(const std::string& k, const Range& r) const { return numberOf(j_.at(k), k, r, false); }
  int integer(const std::string& k, const Range& r) const { return static_cast<int>(numberOf(j_.at(k), k, r, true)); }
  bool flag(const std::string& k) const {
    const json& v = j_.at(k);
    if (!v.is_boolean()) throw HttpError(400, k + ": expected true or false, got " + quote(v));
    return v.get<bool>();
  }
  std::string text(const std::string& k, size_t maxLength = 1000) const {
    const json& v = j_.at(k);
    if (!v.is_string()) throw HttpError(400, k + ": expected a string, got " + quote(v));
    std::string s = v.get<std::string>();
    if (s.size() > maxLength)
      throw HttpError(400, k + ": expected at most " + std::to_string(maxLength) + " characters, got " +
                               std::to_string(s.size()));
    return s;
  }
  Vec3 vec3(const std::string& k, const Range& r) const {
    const json& v = j_.at(k);
    if (!v.is_array() || v.size() != 3) throw HttpError(400, k + ": expected [x, y, z], got " + quote(v));
    Vec3 x;
    for (int i = 0; i < 3; ++i) x[i] = numberOf(v[static_cast<size_t>(i)], k + "[" + std::to_string(i) + "]", r, false);
    return x;
  }
  std::pair<double, double> pair(const std::string& k, const Range& r) const {
    const json& v = j_.at(k);
    if (!v.is_array() || v.size() != 2) throw HttpError(400, k + ": expected [a, b], got " + quote(v));
    return {numberOf(v[0], k + "[0]", r, false), numberOf(v[1], k + "[1]", r, false)};
  }

  static double numberOf(const json& v, const std::string& name, const Range& r, bool integer) {
    const std::string expected = r.expected(integer);
    if (!v.is_number()) throw HttpError(400, name + ": expected " + expected + ", got " + quote(v));
    const double x = v.get<double>();
    if (!std::isfinite(x) || !r.contains(x) || (integer && x != std::floor(x)))
      throw HttpError(400, name + ": expected " + expected + ", got " + quote(v));
    return x;
  }

 private:
  json j_;
};

json vec(const Vec3& v) { return json::array({v.x(), v.y(), v.z()}); }

std::string randomId() {
  static std::mutex m;
  static std::mt19937_64 rng(std::random_device{}());
  std::lock_guard<std::mutex> lk(m);
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(rng()));
  return buf;
}

// A method spec that gives the overrides: "a5:n=8:kappa=0.9".
std::string methodText(const SolverOverrides& o) {
  std::string s = o.algorithm ? algorithmName(*o.algorithm) : "scene";
  for (const SettingSpec& spec : settingTable()) {
    if (std::string(spec.key) == "algorithm" || !spec.isSet(o)) continue;
    const std::string name = spec.alias[0] && static_cast<unsigned char>(spec.alias[0]) < 0x80 ? spec.alias : spec.key;
    s += ":" + name + "=" + spec.valueText(o);
  }
  return s;
}

json settingsJson(const SolverSettings& s) {
  return {{"algorithm", algorithmName(s.algorithm)},
          {"dt", s.dt},
          {"substeps", s.substeps},
          {"iterations", s.iterations},
          {"omega", s.omega},
          {"tolerance", s.tolerance},
          {"kappa", s.kappa},
          {"tau", s.tau},
          {"slop", s.slop},
          {"warm_start", s.warmStart},
          {"block_solve", s.blockSolve},
          {"contact_blocks", s.contactBlocks},
          {"split_impulse", s.splitImpulse},
          {"motor_unscaled", s.motorUnscaled},
          {"friction_exempt", s.frictionExempt},
          {"speculative", s.speculative},
          {"restitution", s.restitution},
          {"islands", s.islands},
          {"restitution_threshold", s.restitutionThreshold},
          {"jacobians", s.jacobians == JacobianRefresh::Joints ? "joints" : "stable"},
          {"gyroscopic", s.gyroscopic == Gyroscopic::None       ? "none"
                         : s.gyroscopic == Gyroscopic::Explicit ? "explicit"
                                                                : "implicit"},
          {"contact_hertz", s.contactHertz},
          {"contact_damping", s.contactDamping},
          {"joint_hertz", s.jointHertz},
          {"joint_damping", s.jointDamping},
          {"push_out", s.pushOut}};
}

const char* kindName(SettingKind k) {
  switch (k) {
    case SettingKind::Integer: return "integer";
    case SettingKind::Real: return "number";
    case SettingKind::Flag: return "flag";
    case SettingKind::Choice: return "choice";
  }
  return "?";
}

json clipJson(const ClipInfo& c, const std::string& sessionId) {
  json j = {{"id", c.id}, {"mode", c.mode}, {"seconds", c.seconds}, {"state", c.state}, {"frames", c.frames}};
  if (!c.error.empty()) j["error"] = c.error;
  if (c.state == "done") {
    j["bytes"] = c.bytes;
    j["url"] = "/api/sessions/" + sessionId + "/clips/" + std::to_string(c.id) + ".mp4";
  }
  return j;
}

json statsJson(const LiveStats& s) {
  json panels = json::array();
  for (const LivePanelStats& p : s.panels)
    panels.push_back({{"name", p.name},
                      {"settings", p.settings},
                      {"time", p.time},
                      {"steps", p.steps},
                      {"step_ms", p.stepMs},
                      {"s1_ms", 1e3 * p.stages.s1},
                      {"s2_ms", 1e3 * p.stages.s2},
                      {"s3_ms", 1e3 * p.stages.s3},
                      {"s4_ms", 1e3 * p.stages.s4},
                      {"contacts", p.contacts},
                      {"manifolds", p.manifolds},
                      {"pairs", p.pairs},
                      {"penetration", p.penetration},
                      {"joint_error", p.jointError},
                      {"kinetic", p.kinetic},
                      {"potential", p.potential},
                      {"diverged", p.diverged},
                      {"problem", p.problem}});
  return {{"seq", s.seq},          {"frames", s.frames},   {"playing", s.playing},     {"seeking", s.seeking},
          {"speed", s.speed},      {"achieved", s.achieved}, {"behind", s.behind},     {"fps", s.fps},
          {"physics_ms", s.physicsMs}, {"draw_ms", s.drawMs}, {"encode_ms", s.encodeMs}, {"jpeg_bytes", s.jpegBytes},
          {"status", s.status},    {"panels", panels}};
}

const char* contentType(const std::string& ext) {
  static const std::map<std::string, const char*> types = {
      {".html", "text/html; charset=utf-8"}, {".js", "text/javascript; charset=utf-8"},
      {".mjs", "text/javascript; charset=utf-8"}, {".css", "text/css; charset=utf-8"},
      {".json", "application/json"}, {".svg", "image/svg+xml"}, {".png", "image/png"},
      {".jpg", "image/jpeg"}, {".ico", "image/x-icon"}, {".txt", "text/plain; charset=utf-8"},
      {".csv", "text/csv; charset=utf-8"}, {".mp4", "video/mp4"}, {".woff2", "font/woff2"},
      {".md", "text/markdown; charset=utf-8"}};
  const auto it = types.find(ext);
  return it == types.end() ? nullptr : it->second;
}

// A session of the API: the scene by name, the method of each panel with the settings the user
// changed, and the live session that steps and draws them.
struct WebSession {
  struct PanelState {
    SolverOverrides user;  // the method's settings and the user's changes over the scene's
  };
  std::string id;
  std::mutex m;  // scene, panels (the live session has its own lock)
  std::string sceneName;
  std::shared_ptr<const Scene> scene;
  std::vector<PanelState> panels;
  std::string clipFolder;
  std::unique_ptr<LiveSession> live;
};

}  // namespace

struct Server::Impl {
  ServerOptions o;
  httplib::Server http;
  std::string ffmpeg, scratch;
  std::atomic<bool> stopping{false};
  std::mutex sessionsM;
  std::map<std::string, std::shared_ptr<WebSession>> sessions;
  std::mutex scenesM;
  std::map<std::string, std::shared_ptr<const Scene>> sceneCache;
  // One frame drawn at a time (llvmpipe uses both cores) and one JPEG encoded, whichever session.
  std::shared_ptr<FairGate> drawGate = std::make_shared<FairGate>(1), encodeGate = std::make_shared<FairGate>(1);
  std::thread reaper;
  std::mutex reaperM;
  std::condition_variable reaperCv;
  std::vector<std::pair<std::string, std::regex>> routes;  // for 405 answers

  explicit Impl(ServerOptions options) : o(std::move(options)) {}

  // --- answers ---

  static void sendJson(Response& res, const json& j, int status = 200) {
    res.status = status;
    res.set_header("Cache-Control", "no-store");
    res.set_content(j.dump(), "application/json");
  }
  static void sendError(Response& res, int status, const std::string& message) {
    sendJson(res, {{"error", message}}, status);
  }

  template <class H>
  void route(const char* method, const std::string& pattern, H h) {
    routes.emplace_back(method, std::regex(pattern));
    auto wrapped = [this, h](const Request& req, Response& res) {
      try {
        h(req, res);
      } catch (const HttpError& e) {
        sendError(res, e.status, e.what());
      } catch (const UsageError& e) {
        sendError(res, 400, e.what());
      } catch (const std::exception& e) {
        sendError(res, 500, e.what());
      }
    };
    const std::string m = method;
    if (m == "GET") http.Get(pattern, wrapped);
    if (m == "POST") http.Post(pattern, wrapped);
    if (m == "DELETE") http.Delete(pattern, wrapped);
  }

  // --- scenes ---

  std::vector<std::string> sceneNames() const {
    std::vector<std::string> names;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(o.scenesDir, ec))
      if (e.path().extension() == ".json" && e.is_regular_file()) names.push_back(e.path().stem().string());
    std::sort(names.begin(), names.end());
    return names;
  }

  std::shared_ptr<const Scene> scene(const std::string& name, const std::string& field) {
    const std::vector<std::string> names = sceneNames();
    if (std::find(names.begin(), names.end(), name) == names.end())
      throw HttpError(400, field + ": expected one of " + joined(names) + ", got " + quote(json(name)));
    std::lock_guard<std::mutex> lk(scenesM);
    auto& s = sceneCache[name];
    if (!s) {
      try {
        s = std::make_shared<const Scene>(loadScene(o.scenesDir + "/" + name + ".json"));
      } catch (const SceneError& e) {
        throw HttpError(500, std::string("scene ") + name + " does not load: " + e.what());
      }
    }
    return s;
  }

  // --- sessions ---

  HttpError noSuchSession(const std::string& id) const {
    return HttpError(404, "no session \"" + id.substr(0, 40) + "\" (closed, or expired after " +
                              numberText(o.idleTimeout) + " s without a request or a stream)");
  }

  std::shared_ptr<WebSession> session(const Request& req) {
    const std::string id = req.matches[1];
    std::lock_guard<std::mutex> lk(sessionsM);
    const auto it = sessions.find(id);
    if (it == sessions.end()) throw noSuchSession(id);
    it->second->live->touch();
    return it->second;
  }

  static SolverOverrides methodOverrides(const std::string& text, const std::string& field) {
    std::vector<MethodSpec> specs;
    try {
      specs = parseMethodSpecs(text);
    } catch (const std::invalid_argument& e) {
      throw HttpError(400, field + ": " + e.what());
    }
    if (specs.size() != 1)
      throw HttpError(400, field + ": expected one method, e.g. a5:n=4:kappa=0.85 (panels take 1 to 4), got " +
                               std::to_string(specs.size()));
    return specs[0].overrides;
  }

  // "a2:m=4,a5:n=4" or ["a2:m=4", "a5:n=4"]: 1 to 4 panels.
  static std::vector<SolverOverrides> panelsOf(const json& v, const std::string& field) {
    std::string text;
    if (v.is_string()) {
      text = v.get<std::string>();
    } else if (v.is_array()) {
      for (const json& x : v) {
        if (!x.is_string()) throw HttpError(400, field + ": expected method specs as strings, got " + quote(x));
        text += (text.empty() ? "" : ",") + x.get<std::string>();
      }
    } else {
      throw HttpError(400, field + ": expected methods, e.g. \"a2:m=4,a5:n=4\", got " + quote(v));
    }
    if (text.size() > 1000) throw HttpError(400, field + ": expected at most 1000 characters");
    std::vector<MethodSpec> specs;
    try {
      specs = parseMethodSpecs(text);
    } catch (const std::invalid_argument& e) {
      throw HttpError(400, field + ": " + e.what());
    }
    if (specs.empty() || static_cast<int>(specs.size()) > kMaxPanels)
      throw HttpError(400, field + ": expected 1 to " + std::to_string(kMaxPanels) + " methods, got " +
                               std::to_string(specs.size()));
    std::vector<SolverOverrides> r;
    for (const MethodSpec& s : specs) r.push_back(s.overrides);
    return r;
  }

  static std::vector<PanelSetup> setups(const Scene& scene, const std::vector<WebSession::PanelState>& panels) {
    std::vector<PanelSetup> r;
    for (size_t i = 0; i < panels.size(); ++i) {
      try {
        r.push_back({resolveSettings(scene, panels[i].user), panels.size() > 1 ? methodText(panels[i].user) : ""});
      } catch (const UsageError& e) {
        throw HttpError(400, (panels.size() > 1 ? "panel " + std::to_string(i) + ": " : std::string()) + e.what());
      }
    }
    return r;
  }

  json stateJson(WebSession& s) {
    std::lock_guard<std::mutex> lk(s.m);
    json j = s.live->read([&](const RenderSession& r, const Look& look) {
      json panels = json::array();
      for (int i = 0; i < r.panelCount(); ++i) {
        const Panel& p = r.panel(i);
        panels.push_back({{"method", methodText(s.panels[static_cast<size_t>(i)].user)},
                          {"settings", settingsJson(p.settings())},
                          {"line", settingsLine(p.settings())},
                          {"time", p.state().time},
                          {"diverged", p.diverged()},
                          {"problem", p.problem()}});
      }
      const CameraPreset& c = look.camera;
      json cameras = json::array();
      for (const CameraPreset& p : s.scene->cameras) cameras.push_back(p.name);
      cameras.push_back("fitted");
      json bodies = json::array();
      for (const Body& b : s.scene->model.bodies)
        if (!b.isStatic) bodies.push_back(b.name);
      return json{{"panels", panels},
                  {"time", r.panel(0).state().time},
                  {"camera",
                   {{"preset", c.name},
                    {"yaw", c.yaw},
                    {"pitch", c.pitch},
                    {"distance", c.distance},
                    {"fov", c.fovY},
                    {"target", vec(c.target)},
                    {"follow", c.follow},
                    {"orbit", look.orbit}}},
                  {"cameras", cameras},
                  {"bodies", bodies},
                  {"view",
                   {{"colour", colourModeName(look.view.colour)},
                    {"contacts", look.view.contacts},
                    {"joints", look.view.joints},
                    {"hud", look.view.hud},
                    {"speed_scale", look.view.speedScale},
                    {"error_scale", look.view.errorScale}}}};
    });
    const LiveStats st = s.live->stats();
    json clips = json::array();
    for (const ClipInfo& c : s.live->clips()) clips.push_back(clipJson(c, s.id));
    j["id"] = s.id;
    j["scene"] = s.sceneName;
    j["description"] = s.scene->description;
    j["width"] = s.live->config().width;
    j["height"] = s.live->config().height;
    j["fps"] = s.live->config().fps;
    j["playing"] = s.live->playing();
    j["speed"] = st.speed;
    j["status"] = st.status;
    j["viewers"] = s.live->viewers();
    j["clips"] = clips;
    j["urls"] = {{"stream", "/api/sessions/" + s.id + "/stream.mjpeg"},
                 {"events", "/api/sessions/" + s.id + "/events"},
                 {"frame", "/api/sessions/" + s.id + "/frame.png"}};
    return j;
  }

  void createSession(const Request& req, Response& res) {
    const Fields f(req, {"scene", "method", "methods", "size", "fps", "play", "speed"});
    if (!f.has("scene")) throw HttpError(400, "scene: expected a scene name (GET /api/scenes lists them)");
    auto s = std::make_shared<WebSession>();
    s->sceneName = f.text("scene", 200);
    s->scene = scene(s->sceneName, "scene");
    if (f.has("method") && f.has("methods")) throw HttpError(400, "method, methods: give one of them");
    if (f.has("method"))
      s->panels.push_back({methodOverrides(f.text("method"), "method")});
    else if (f.has("methods"))
      for (const SolverOverrides& o : panelsOf(f.at("methods"), "methods")) s->panels.push_back({o});
    else
      s->panels.push_back({});
    LiveConfig c;
    c.width = o.width;
    c.height = o.height;
    if (f.has("size")) {
      const std::string size = f.text("size", 20);
      try {
        parseFrameSize(size, c.width, c.height);
      } catch (const UsageError&) {
        c.width = -1;
      }
      if (c.width < kMinSide || c.height < kMinSide || c.width > kMaxWidth || c.height > kMaxHeight)
        throw HttpError(400, "size: expected WIDTHxHEIGHT from " + std::to_string(kMinSide) + "x" +
                                 std::to_string(kMinSide) + " to " + std::to_string(kMaxWidth) + "x" +
                                 std::to_string(kMaxHeight) + ", got " + quote(json(size)));
    }
    c.fps = f.has("fps") ? f.integer("fps", {1, 60}) : o.fps;
    const double speed = f.has("speed") ? f.number("speed", {0.01, 10}) : 1.0;
    const bool play = f.has("play") && f.flag("play");
    c.jpegQuality = o.jpegQuality;
    c.historySeconds = o.history;
    c.ffmpeg = ffmpeg;
    c.drawGate = drawGate;
    c.encodeGate = encodeGate;
    const std::vector<PanelSetup> ps = setups(*s->scene, s->panels);
    Look look;
    look.camera = chooseCamera(*s->scene, {});
    look.stepCost = true;

    std::lock_guard<std::mutex> lk(sessionsM);
    if (stopping) throw HttpError(503, "the server is stopping");
    if (static_cast<int>(sessions.size()) >= o.maxSessions) {
      res.set_header("Retry-After", "10");
      throw HttpError(503, "the server holds its limit of " + std::to_string(o.maxSessions) +
                               " sessions (--max-sessions); close another tab, or wait for an idle one to expire (" +
                               numberText(o.idleTimeout) + " s)");
    }
    do s->id = randomId();
    while (sessions.count(s->id));
    s->clipFolder = scratch + "/" + s->id;
    fs::create_directories(s->clipFolder);
    c.clipFolder = s->clipFolder;
    try {
      s->live = std::make_unique<LiveSession>(s->scene, ps, look, c);
    } catch (const PanelError& e) {
      throw HttpError(400, e.what());
    }
    if (play) s->live->play(speed);
    sessions[s->id] = s;
    log("session " + s->id + " opened: " + s->sceneName + ", " + std::to_string(sessions.size()) + " open");
    sendJson(res, stateJson(*s), 201);
  }

  void closeSession(const std::shared_ptr<WebSession>& s, const std::string& why) {
    s->live->close();
    std::error_code ec;
    fs::remove_all(s->clipFolder, ec);
    log("session " + s->id + " closed (" + why + ")");
    trimMemory();
  }

  void removeSession(const std::string& id, const std::string& why) {
    std::shared_ptr<WebSession> s;
    {
      std::lock_guard<std::mutex> lk(sessionsM);
      const auto it = sessions.find(id);
      if (it == sessions.end()) return;
      s = it->second;
      sessions.erase(it);
    }
    closeSession(s, why);
  }

  // glibc keeps what frames freed (megabytes each, from many threads) for reuse rather than giving
  // it back; a closed session's memory, and what streaming leaves free, go back to the system.
  static void trimMemory() { malloc_trim(0); }

  void reap() {
    std::unique_lock<std::mutex> lk(reaperM);
    double lastTrim = nowSeconds();
    while (!stopping) {
      reaperCv.wait_for(lk, std::chrono::milliseconds(250));
      if (nowSeconds() - lastTrim > 5) {
        trimMemory();
        lastTrim = nowSeconds();
      }
      std::vector<std::string> idle;
      {
        std::lock_guard<std::mutex> sl(sessionsM);
        for (const auto& [id, s] : sessions)
          if (s->live->idleSeconds() > o.idleTimeout) idle.push_back(id);
      }
      for (const std::string& id : idle) removeSession(id, "idle for " + numberText(o.idleTimeout) + " s");
    }
  }

  void log(const std::string& line) {
    static std::mutex m;
    std::lock_guard<std::mutex> lk(m);
    std::cout << line << std::endl;
  }

  // --- settings, panels, scene ---

  void setSettings(WebSession& s, const Request& req) {
    const Fields f(req, {"panel", "method", "settings"});
    std::lock_guard<std::mutex> lk(s.m);
    const int n = static_cast<int>(s.panels.size());
    std::vector<int> targets;
    if (f.has("panel"))
      targets.push_back(f.integer("panel", {0, static_cast<double>(n - 1)}));
    else
      for (int i = 0; i < n; ++i) targets.push_back(i);
    std::vector<WebSession::PanelState> next = s.panels;
    for (int i : targets) {
      SolverOverrides& u = next[static_cast<size_t>(i)].user;
      if (f.has("method")) u = methodOverrides(f.text("method"), "method");
      if (!f.has("settings")) continue;
      const json& set = f.at("settings");
      if (!set.is_object()) throw HttpError(400, "settings: expected an object of setting: value, got " + quote(set));
      // A new algorithm starts from its own defaults: n, κ, τ of another one may not apply.
      if (set.contains("algorithm") || set.contains("algo")) u = SolverOverrides{};
      for (const auto& [key, v] : set.items()) {
        const SettingSpec* spec = findSetting(key);
        const std::string name = "settings." + key.substr(0, limits::kMaxMessageValue);
        if (!spec) throw HttpError(400, name + ": unknown setting; expected one of algorithm, " + settingKeys());
        try {
          if (v.is_null())
            spec->clear(u);
          else if (v.is_boolean())
            spec->setFlag(u, v.get<bool>());
          else if (v.is_number())
            spec->setNumber(u, v.get<double>());
          else if (v.is_string())
            spec->setText(u, v.get<std::string>());
          else
            throw std::invalid_argument("expected " + spec->expected() + ", got " + quote(v));
        } catch (const std::invalid_argument& e) {
          throw HttpError(400, name + ": " + e.what());
        }
      }
    }
    if (!f.has("method") && !f.has("settings")) throw HttpError(400, "method, settings: give a method or settings to change");
    const std::vector<PanelSetup> ps = setups(*s.scene, next);  // every panel checked before any changes
    s.live->change([&](RenderSession& r, Look&) {
      for (int i : targets) r.setSettings(i, ps[static_cast<size_t>(i)].settings);
    });
    s.panels = std::move(next);
  }

  void setPanels(WebSession& s, const Request& req) {
    const Fields f(req, {"methods"});
    if (!f.has("methods")) throw HttpError(400, "methods: expected 1 to 4 methods, e.g. \"a2:m=4,a5:n=4\"");
    std::lock_guard<std::mutex> lk(s.m);
    std::vector<WebSession::PanelState> next;
    for (const SolverOverrides& o : panelsOf(f.at("methods"), "methods")) next.push_back({o});
    const std::vector<PanelSetup> ps = setups(*s.scene, next);
    try {
      s.live->restart([&](RenderSession& r, Look&) { r.setPanels(ps); });
    } catch (const PanelError& e) {
      throw HttpError(400, "methods: panel " + std::to_string(e.panel) + ": " + e.what());
    }
    s.panels = std::move(next);
  }

  void setScene(WebSession& s, const Request& req) {
    const Fields f(req, {"scene", "methods"});
    if (!f.has("scene")) throw HttpError(400, "scene: expected a scene name (GET /api/scenes lists them)");
    const std::string name = f.text("scene", 200);
    std::shared_ptr<const Scene> sc = scene(name, "scene");
    std::lock_guard<std::mutex> lk(s.m);
    std::vector<WebSession::PanelState> next;
    if (f.has("methods"))
      for (const SolverOverrides& o : panelsOf(f.at("methods"), "methods")) next.push_back({o});
    else
      next.resize(s.panels.size());  // as many panels, each with the new scene's own settings
    const std::vector<PanelSetup> ps = setups(*sc, next);
    try {
      s.live->restart([&](RenderSession& r, Look& look) {
        r.setScene(sc, ps);
        look.camera = chooseCamera(*sc, {});
        look.orbit = 0;
        look.view.highlight.clear();
      });
    } catch (const PanelError& e) {
      throw HttpError(400, "panel " + std::to_string(e.panel) + ": " + e.what());
    }
    s.scene = sc;
    s.sceneName = name;
    s.panels = std::move(next);
  }

  // --- camera, view, picking ---

  void setCamera(WebSession& s, const Request& req) {
    const Fields f(req, {"preset", "yaw", "pitch", "distance", "fov", "target", "follow", "orbit", "rotate", "zoom", "pan"});
    // Every value is read (and checked) before the camera changes.
    std::optional<std::string> preset, follow;
    if (f.has("preset")) preset = f.text("preset", limits::kMaxNameLength);
    if (f.has("follow")) follow = f.text("follow", limits::kMaxNameLength);
    std::optional<double> yaw, pitch, distance, fov, orbit, zoom;
    if (f.has("yaw")) yaw = f.number("yaw", limits::kDegrees);
    if (f.has("pitch")) pitch = f.number("pitch", {-89, 89});
    if (f.has("distance")) distance = f.number("distance", limits::kDistance);
    if (f.has("fov")) fov = f.number("fov", {5, 150});
    if (f.has("orbit")) orbit = f.number("orbit", {-1e4, 1e4});
    if (f.has("zoom")) zoom = f.number("zoom", {0.01, 100});
    std::optional<Vec3> target;
    if (f.has("target")) target = f.vec3("target", limits::kCoordinate);
    std::optional<std::pair<double, double>> rotate, pan;
    if (f.has("rotate")) rotate = f.pair("rotate", {-360, 360});
    if (f.has("pan")) pan = f.pair("pan", {-1e4, 1e4});
    const int height = s.live->config().height;
    std::lock_guard<std::mutex> lk(s.m);
    const Scene& sc = *s.scene;
    if (follow && !follow->empty()) {
      const int b = sc.model.bodyIndex(*follow);
      if (b < 0 || sc.model.bodies[static_cast<size_t>(b)].isStatic)
        throw HttpError(400, "follow: expected the name of a dynamic body of " + s.sceneName + ", or \"\" for none, got " +
                                 quote(json(*follow)));
    }
    std::optional<CameraPreset> chosen;
    if (preset) {
      if (*preset == "fitted") {
        chosen = s.live->read([&](const RenderSession& r, const Look&) { return fittedCamera(sc.model, r.panel(0).state()); });
      } else {
        for (const CameraPreset& c : sc.cameras)
          if (c.name == *preset) chosen = c;
        if (!chosen) {
          std::vector<std::string> names;
          for (const CameraPreset& c : sc.cameras) names.push_back(c.name);
          names.push_back("fitted");
          throw HttpError(400, "preset: expected one of " + joined(names) + ", got " + quote(json(*preset)));
        }
      }
    }
    s.live->change([&](RenderSession& r, Look& look) {
      CameraPreset& c = look.camera;
      if (chosen) c = *chosen;
      if (yaw) c.yaw = *yaw;
      if (pitch) c.pitch = *pitch;
      if (distance) c.distance = *distance;
      if (fov) c.fovY = *fov;
      if (target) c.target = *target, c.follow.clear();
      if (follow) c.follow = *follow;
      if (orbit) look.orbit = *orbit;
      if (rotate) {
        c.yaw = std::remainder(c.yaw + rotate->first, 360.0);
        c.pitch = std::clamp(c.pitch + rotate->second, -89.0, 89.0);
      }
      if (zoom) c.distance = std::clamp(c.distance * *zoom, limits::kDistance.lo, limits::kDistance.hi);
      if (pan) {
        // Pixels of the frame to metres at the target: the scene follows the mouse.
        const Camera cam = placeCamera(c, sc.model, r.panel(0).state(), look.orbit);
        const Vec3 f = (cam.target - cam.eye).normalized().cast<double>();
        Vec3 right = f.cross(Vec3::UnitY());
        if (right.norm() < 1e-9) right = Vec3::UnitX();
        right.normalize();
        const Vec3 up = right.cross(f);
        const double perPixel = 2 * c.distance * std::tan(0.5 * c.fovY * M_PI / 180) / height;
        c.target = cam.target.cast<double>() - right * pan->first * perPixel + up * pan->second * perPixel;
        c.follow.clear();
        for (int i = 0; i < 3; ++i) c.target[i] = std::clamp(c.target[i], limits::kCoordinate.lo, limits::kCoordinate.hi);
      }
    });
  }

  void setView(WebSession& s, const Request& req) {
    const Fields f(req, {"colour", "color", "contacts", "joints", "hud", "speed_scale", "error_scale", "highlight"});
    std::optional<ColourMode> colour;
    for (const char* k : {"colour", "color"})
      if (f.has(k)) {
        colour = parseColourMode(f.text(k, 40));
        if (!colour)
          throw HttpError(400, std::string(k) + ": expected auto, body, group, speed, activity or error, got " +
                                   quote(f.at(k)));
      }
    std::optional<double> speedScale, errorScale;
    if (f.has("speed_scale")) speedScale = f.number("speed_scale", {1e-9, 1e9});
    if (f.has("error_scale")) errorScale = f.number("error_scale", {1e-12, 1e9});
    std::optional<bool> contacts, joints, hud;
    if (f.has("contacts")) contacts = f.flag("contacts");
    if (f.has("joints")) joints = f.flag("joints");
    if (f.has("hud")) hud = f.flag("hud");
    std::optional<std::vector<std::string>> highlight;
    std::lock_guard<std::mutex> lk(s.m);
    if (f.has("highlight")) {
      const json& h = f.at("highlight");
      if (!h.is_array()) throw HttpError(400, "highlight: expected a list of body names, got " + quote(h));
      highlight.emplace();
      for (const json& x : h) {
        if (!x.is_string() || s.scene->model.bodyIndex(x.get<std::string>()) < 0)
          throw HttpError(400, "highlight: expected names of bodies of " + s.sceneName + ", got " + quote(x));
        highlight->push_back(x.get<std::string>());
      }
    }
    s.live->change([&](RenderSession&, Look& look) {
      if (colour) look.view.colour = *colour;
      if (contacts) look.view.contacts = *contacts;
      if (joints) look.view.joints = *joints;
      if (hud) look.view.hud = *hud;
      if (speedScale) look.view.speedScale = *speedScale;
      if (errorScale) look.view.errorScale = *errorScale;
      if (highlight) look.view.highlight = *highlight;
    });
  }

  std::pair<double, double> pixel(const Fields& f, const WebSession& s) {
    if (!f.has("x") || !f.has("y")) throw HttpError(400, "x, y: expected the pixel of the frame, e.g. {\"x\": 640, \"y\": 360}");
    const int w = s.live->config().width, h = s.live->config().height;
    return {f.number("x", {0, static_cast<double>(w), false, true}), f.number("y", {0, static_cast<double>(h), false, true})};
  }

  json pickJson(const RenderSession::Pick& p, const Scene& sc) {
    json j = {{"panel", p.panel}, {"hit", p.hit.body >= 0}, {"ray", {{"origin", vec(p.origin)}, {"direction", vec(p.direction)}}}};
    if (p.hit.body >= 0) {
      j["body"] = p.hit.body;
      j["name"] = sc.model.bodies[static_cast<size_t>(p.hit.body)].name;
      j["point"] = vec(p.hit.point);
      j["normal"] = vec(p.hit.normal);
      j["distance"] = p.hit.distance;
    }
    return j;
  }

  json pick(WebSession& s, const Request& req) {
    const Fields f(req, {"x", "y"});
    const auto xy = pixel(f, s);
    const auto x = xy.first, y = xy.second;  // not a structured binding: C++17 lambdas cannot capture one
    const int w = s.live->config().width, h = s.live->config().height;
    std::lock_guard<std::mutex> lk(s.m);
    return pickJson(s.live->read([&](const RenderSession& r, const Look&) { return r.pick(w, h, x, y); }), *s.scene);
  }

  json push(WebSession& s, const Request& req) {
    const Fields f(req, {"x", "y", "speed", "body", "impulse", "point"});
    const int w = s.live->config().width, h = s.live->config().height;
    std::lock_guard<std::mutex> lk(s.m);
    const Model& model = s.scene->model;
    if (f.has("body")) {  // a given impulse on a named body
      if (f.has("x") || f.has("y") || f.has("speed")) throw HttpError(400, "body: give body and impulse, or x and y, not both");
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
    const auto xy = pixel(f, s);
    const auto x = xy.first, y = xy.second;
    const double speed = f.has("speed") ? f.number("speed", {0, 100, true}) : 3.0;
    return s.live->change([&](RenderSession& r, Look&) {
      const RenderSession::Pick p = r.pick(w, h, x, y);
      json j = pickJson(p, *s.scene);
      if (p.hit.body < 0) return j;
      // The speed the push gives the body's centre along the ray (a mass-independent feel).
      const Vec3 impulse = model.bodies[static_cast<size_t>(p.hit.body)].mass * speed * p.direction;
      r.push(p.panel, p.hit.body, impulse, p.hit.point);
      j["impulse"] = vec(impulse);
      return j;
    });
  }

  // --- static files ---

  // The file under `root` that `rel` names, or "" when it names none: no "..", no hidden or
  // empty segment, no symlink anywhere on the way, a regular file inside the root.
  static std::string staticFile(const std::string& root, const std::string& rel) {
    if (root.empty() || rel.empty() || rel.size() > 512 || rel.front() == '/' ||
        rel.find_first_of(std::string("\\\0:", 3)) != std::string::npos)
      return "";
    std::string path = root;
    std::stringstream ss(rel);
    std::string seg;
    while (std::getline(ss, seg, '/')) {
      if (seg.empty() || seg[0] == '.') return "";  // "..", ".", hidden files, "//"
      path += "/" + seg;
      struct stat st {};
      if (lstat(path.c_str(), &st) != 0 || S_ISLNK(st.st_mode)) return "";
    }
    if (rel.back() == '/') return "";
    struct stat st {};
    if (lstat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return "";
    std::error_code ec;
    const std::string canon = fs::canonical(path, ec).string(), rootCanon = fs::canonical(root, ec).string();
    if (ec || canon.compare(0, rootCanon.size() + 1, rootCanon + "/") != 0) return "";
    return canon;
  }

  void serveFile(const std::string& root, const std::string& rel, Response& res) {
    const std::string path = staticFile(root, rel);
    const char* type = contentType(fs::path(rel).extension().string());
    if (path.empty() || !type) throw HttpError(404, "no such file");
    std::ifstream in(path, std::ios::binary);
    std::string body((std::istreambuf_iterator<char>(in)), {});
    if (!in && !in.eof()) throw HttpError(500, "cannot read the file");
    res.set_header("Cache-Control", "no-cache");
    res.set_header("X-Content-Type-Options", "nosniff");
    res.set_content(std::move(body), type);
  }

  json labFiles() {
    json files = json::array();
    if (o.labDir.empty()) return files;
    std::error_code ec;
    std::vector<std::string> names;
    for (auto it = fs::recursive_directory_iterator(o.labDir, ec); !ec && it != fs::recursive_directory_iterator();
         it.increment(ec)) {
      const std::string rel = fs::relative(it->path(), o.labDir, ec).string();
      const std::string ext = it->path().extension().string();
      if ((ext == ".html" || ext == ".svg" || ext == ".png") && !staticFile(o.labDir, rel).empty()) names.push_back(rel);
      if (names.size() >= 500) break;
    }
    std::sort(names.begin(), names.end());
    for (const auto& n : names) files.push_back({{"name", n}, {"url", "/lab/" + n}});
    return files;
  }

  // No route for the method and path: 405 naming the methods the path has, else 404.
  void notFound(const Request& req, Response& res) {
    std::vector<std::string> allowed;
    for (const auto& [m, re] : routes)
      if (m != req.method && std::regex_match(req.path, re) && std::find(allowed.begin(), allowed.end(), m) == allowed.end())
        allowed.push_back(m);
    const std::string what = req.method + " " + req.path.substr(0, 200);
    if (allowed.empty()) return sendError(res, 404, "no such path: " + what + " (docs/server.md lists the API)");
    res.set_header("Allow", joined(allowed));
    sendError(res, 405, what + ": expected " + joined(allowed));
  }

  // --- the routes ---

  void routesSetUp();
};

void Server::Impl::routesSetUp() {
  const std::string sid = R"(/api/sessions/([0-9a-f]{16}))";
  const std::string anyId = R"(/api/sessions/([^/]+))";

  route("GET", "/api/scenes", [this](const Request&, Response& res) {
    json list = json::array();
    for (const std::string& name : sceneNames()) {
      json j = {{"name", name}};
      try {
        const std::shared_ptr<const Scene> s = scene(name, "scene");
        json cams = json::array();
        for (const CameraPreset& c : s->cameras) cams.push_back(c.name);
        j["description"] = s->description.substr(0, s->description.find('\n'));
        j["bodies"] = s->model.dynamicCount();
        j["joints"] = s->model.joints.size();
        j["cameras"] = cams;
        try {
          j["solver"] = methodText(s->solver.empty() ? SolverOverrides{} : s->solver);
          j["settings"] = settingsLine(resolveSettings(*s, {}));
        } catch (const UsageError& e) {
          j["error"] = e.what();
        }
      } catch (const HttpError& e) {
        j["error"] = e.what();
      }
      list.push_back(j);
    }
    sendJson(res, {{"scenes", list}});
  });

  route("GET", "/api/methods", [](const Request&, Response& res) {
    json algos = json::array();
    for (Algorithm a : {Algorithm::A1, Algorithm::A2, Algorithm::A3, Algorithm::A4, Algorithm::A5, Algorithm::Soft})
      algos.push_back({{"name", algorithmName(a)},
                       {"title", algorithmTitle(a)},
                       {"substeps", subSteps(a)},
                       {"kappa_tau", havokScaled(a)},
                       {"defaults", settingsJson(resolve([&] {
                          SolverOverrides o;
                          o.algorithm = a;
                          return o;
                        }()))}});
    json settings = json::array();
    for (const SettingSpec& s : settingTable()) {
      json j = {{"key", s.key}, {"alias", s.alias}, {"flag", s.flag}, {"kind", kindName(s.kind)},
                {"help", s.help}, {"expected", s.expected()}};
      if (s.kind == SettingKind::Integer || s.kind == SettingKind::Real)
        j["range"] = {{"min", s.range.lo}, {"max", s.range.hi}, {"min_open", s.range.loOpen}, {"max_open", s.range.hiOpen}};
      if (s.kind == SettingKind::Choice) j["choices"] = s.choices;
      settings.push_back(j);
    }
    sendJson(res, {{"algorithms", algos},
                   {"settings", settings},
                   {"colours", {"auto", "body", "group", "speed", "activity", "error"}},
                   {"max_panels", kMaxPanels},
                   {"example", "a5:n=4:kappa=0.85"}});
  });

  route("GET", "/api/server", [this](const Request&, Response& res) {
    size_t n;
    {
      std::lock_guard<std::mutex> lk(sessionsM);
      n = sessions.size();
    }
    sendJson(res, {{"sessions", n},
                   {"max_sessions", o.maxSessions},
                   {"size", std::to_string(o.width) + "x" + std::to_string(o.height)},
                   {"fps", o.fps},
                   {"idle_timeout", o.idleTimeout},
                   {"history", o.history},
                   {"clips", !ffmpeg.empty()},
                   {"lab", !labFiles().empty()}});
  });

  route("GET", "/api/lab", [this](const Request&, Response& res) { sendJson(res, {{"files", labFiles()}}); });

  route("POST", "/api/sessions", [this](const Request& req, Response& res) { createSession(req, res); });

  route("GET", sid, [this](const Request& req, Response& res) { sendJson(res, stateJson(*session(req))); });
  auto del = [this](const Request& req, Response& res) {
    const auto s = session(req);
    removeSession(s->id, "closed by request");
    sendJson(res, {{"closed", s->id}});
  };
  route("DELETE", sid, del);
  route("POST", sid + "/close", del);  // what a closing page can send (navigator.sendBeacon posts)

  auto stateAfter = [this](auto action) {
    return [this, action](const Request& req, Response& res) {
      const auto s = session(req);
      action(*s, req);
      sendJson(res, stateJson(*s));
    };
  };
  route("POST", sid + "/settings", stateAfter([this](WebSession& s, const Request& r) { setSettings(s, r); }));
  route("POST", sid + "/panels", stateAfter([this](WebSession& s, const Request& r) { setPanels(s, r); }));
  route("POST", sid + "/scene", stateAfter([this](WebSession& s, const Request& r) { setScene(s, r); }));
  route("POST", sid + "/camera", stateAfter([this](WebSession& s, const Request& r) { setCamera(s, r); }));
  route("POST", sid + "/view", stateAfter([this](WebSession& s, const Request& r) { setView(s, r); }));
  route("POST", sid + "/play", stateAfter([](WebSession& s, const Request& r) {
          const Fields f(r, {"speed"});
          s.live->play(f.has("speed") ? f.number("speed", {0.01, 10}) : s.live->stats().speed);
        }));
  route("POST", sid + "/pause", stateAfter([](WebSession& s, const Request& r) {
          const Fields f(r, {});
          s.live->pause();
        }));
  route("POST", sid + "/step", stateAfter([](WebSession& s, const Request& r) {
          const Fields f(r, {"count"});
          s.live->step(f.has("count") ? f.integer("count", {1, kMaxSteps}) : 1);
        }));
  route("POST", sid + "/reset", stateAfter([](WebSession& s, const Request& r) {
          const Fields f(r, {});
          s.live->reset();
        }));
  route("POST", sid + "/seek", stateAfter([](WebSession& s, const Request& r) {
          const Fields f(r, {"time"});
          if (!f.has("time")) throw HttpError(400, "time: expected a number in [0, " + numberText(kMaxSeek) + "]");
          s.live->seek(f.number("time", {0, kMaxSeek}));
        }));
  route("POST", sid + "/pick", [this](const Request& req, Response& res) { sendJson(res, pick(*session(req), req)); });
  route("POST", sid + "/push", [this](const Request& req, Response& res) {
    const auto s = session(req);
    try {
      sendJson(res, push(*s, req));
    } catch (const std::invalid_argument& e) {  // World::applyImpulse
      throw HttpError(400, e.what());
    }
  });

  route("GET", sid + "/stats", [this](const Request& req, Response& res) {
    sendJson(res, statsJson(session(req)->live->stats()));
  });

  route("GET", sid + R"(/frame\.png)", [this](const Request& req, Response& res) {
    const auto s = session(req);
    const std::shared_ptr<const Image> img = s->live->image(10.0);
    if (!img) {
      const std::string why = s->live->stats().status;
      throw HttpError(503, "no frame could be drawn" + (why.empty() ? std::string(" in 10 s") : ": " + why));
    }
    const std::vector<uint8_t> png = encodePng(*img);
    char name[96];
    std::snprintf(name, sizeof name, "substep-%s-%.2fs.png", s->sceneName.c_str(), s->live->stats().panels.empty() ? 0.0 : s->live->stats().panels[0].time);
    res.set_header("Content-Disposition", std::string("attachment; filename=\"") + name + "\"");
    res.set_header("Cache-Control", "no-store");
    res.set_content(std::string(png.begin(), png.end()), "image/png");
  });

  route("GET", sid + R"(/stream\.mjpeg)", [this](const Request& req, Response& res) {
    const auto s = session(req);
    if (s->live->viewers() >= kMaxViewers)
      throw HttpError(503, "session " + s->id + " already streams to " + std::to_string(kMaxViewers) + " viewers");
    auto viewer = std::make_shared<LiveSession::Viewer>(*s->live);
    auto seq = std::make_shared<long long>(0);
    res.set_header("Cache-Control", "no-cache, no-store");
    res.set_header("X-Accel-Buffering", "no");
    // Each part is closed by the next boundary at once, so that a browser shows it without
    // waiting for the next frame; while nothing changes, the last frame is sent again every
    // second (that also finds streams whose viewer left).
    res.set_chunked_content_provider(
        "multipart/x-mixed-replace; boundary=substepframe",
        [this, s, viewer, seq](size_t offset, httplib::DataSink& sink) {
          if (offset == 0 && !sink.write("--substepframe\r\n", 16)) return false;
          while (!stopping && !s->live->closed()) {
            const LiveFrame f = s->live->waitFrame(*seq, 1.0);
            if (f.seq == 0) continue;
            const std::string head = "Content-Type: image/jpeg\r\nContent-Length: " + std::to_string(f.jpeg->size()) +
                                     "\r\nX-Sim-Time: " + std::to_string(f.time) + "\r\n\r\n";
            static const std::string tail = "\r\n--substepframe\r\n";
            if (!sink.write(head.data(), head.size()) || !sink.write(f.jpeg->data(), f.jpeg->size()) ||
                !sink.write(tail.data(), tail.size()))
              return false;
            *seq = f.seq;
            return true;
          }
          return false;
        },
        [viewer](bool) {});
  });

  route("GET", sid + "/events", [this](const Request& req, Response& res) {
    const auto s = session(req);
    auto seq = std::make_shared<long long>(0);
    auto last = std::make_shared<double>(0);
    res.set_header("Cache-Control", "no-cache, no-store");
    res.set_chunked_content_provider("text/event-stream", [this, s, seq, last](size_t offset, httplib::DataSink& sink) {
      if (offset == 0 && !sink.write("retry: 2000\n\n", 13)) return false;
      // At most 15 a second: plots need no more, and a slow client gets the latest.
      const double wait = *last + 1.0 / 15 - nowSeconds();
      if (wait > 0) std::this_thread::sleep_for(std::chrono::duration<double>(wait));
      if (stopping || s->live->closed()) return false;
      const LiveStats st = s->live->waitStats(*seq, 1.0);
      s->live->touch();
      std::string msg;
      if (st.seq == *seq)
        msg = ": idle\n\n";
      else
        msg = "event: stats\ndata: " + statsJson(st).dump() + "\n\n";
      *seq = st.seq;
      *last = nowSeconds();
      return sink.write(msg.data(), msg.size());
    });
  });

  route("POST", sid + "/clips", [this](const Request& req, Response& res) {
    const auto s = session(req);
    const Fields f(req, {"mode", "seconds"});
    const std::string mode = f.has("mode") ? f.text("mode", 20) : "last";
    if (mode != "last" && mode != "next") throw HttpError(400, "mode: expected last or next, got " + quote(f.at("mode")));
    const double seconds = f.has("seconds") ? f.number("seconds", {0.1, mode == "last" ? o.history : 60.0}) : 5.0;
    if (ffmpeg.empty()) throw HttpError(503, "clips need the ffmpeg program, which is not on PATH (Debian: apt-get install ffmpeg)");
    int id;
    try {
      id = s->live->record(mode, seconds);
    } catch (const std::invalid_argument& e) {
      throw HttpError(409, e.what());
    }
    sendJson(res, clipJson(*s->live->clip(id), s->id), 202);
  });
  route("GET", sid + "/clips", [this](const Request& req, Response& res) {
    const auto s = session(req);
    json list = json::array();
    for (const ClipInfo& c : s->live->clips()) list.push_back(clipJson(c, s->id));
    sendJson(res, {{"clips", list}});
  });
  auto clipOf = [this](const Request& req, std::shared_ptr<WebSession>& s) {
    s = session(req);
    const std::string n = req.matches[2];
    const std::optional<ClipInfo> c = n.size() < 9 ? s->live->clip(std::stoi(n)) : std::nullopt;
    if (!c) throw HttpError(404, "session " + s->id + " has no clip " + n.substr(0, 20));
    return *c;
  };
  route("GET", sid + R"(/clips/([0-9]+))", [clipOf](const Request& req, Response& res) {
    std::shared_ptr<WebSession> s;
    const ClipInfo c = clipOf(req, s);
    sendJson(res, clipJson(c, s->id));
  });
  route("GET", sid + R"(/clips/([0-9]+)\.mp4)", [this, clipOf](const Request& req, Response& res) {
    std::shared_ptr<WebSession> s;
    const ClipInfo c = clipOf(req, s);
    if (c.state != "done")
      throw HttpError(409, "clip " + std::to_string(c.id) + " is " + c.state + (c.error.empty() ? "" : ": " + c.error));
    serveFile(s->clipFolder, fs::path(c.path).filename().string(), res);
    res.set_header("Content-Disposition", "attachment; filename=\"substep-" + s->sceneName + "-clip" + std::to_string(c.id) + ".mp4\"");
  });

  // Unknown sessions of any shape are 404 too (a well-formed id that is open is answered above);
  // an open session's unknown path is the usual 404 or 405.
  auto noSession = [this](const Request& req, Response& res) {
    const std::string id = req.matches[1];
    {
      std::lock_guard<std::mutex> lk(sessionsM);
      if (sessions.count(id)) return notFound(req, res);
    }
    throw noSuchSession(id);
  };
  route("GET", anyId + "(/.*)?", noSession);
  route("POST", anyId + "(/.*)?", noSession);
  route("DELETE", anyId + "(/.*)?", noSession);

  route("GET", R"(/lab/(.+))", [this](const Request& req, Response& res) {
    if (o.labDir.empty()) throw HttpError(404, "no lab folder (substep serve --lab DIR)");
    serveFile(o.labDir, req.matches[1], res);
  });
  route("GET", "/", [this](const Request&, Response& res) { serveFile(o.webRoot, "index.html", res); });
  route("GET", R"(/(.+))", [this](const Request& req, Response& res) {
    const std::string rel = req.matches[1];
    if (rel.compare(0, 4, "api/") == 0) return notFound(req, res);
    serveFile(o.webRoot, rel, res);
  });

  // Whatever no route answered: 405 when another method has the path, else 404; in JSON.
  http.set_error_handler([this](const Request& req, Response& res) {
    if (!res.body.empty()) return;
    if (res.status == 404) {
      notFound(req, res);
      return;
    }
    if (res.status == 413)
      sendError(res, 413, "the request body is larger than " + std::to_string(o.maxBody) + " bytes");
    else if (res.status == 400)
      sendError(res, 400, "malformed request");
    else
      sendError(res, res.status, "the request could not be answered (HTTP " + std::to_string(res.status) + ")");
  });
}

// --- the server ------------------------------------------------------------------------------

Server::Server(ServerOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {
  Impl& m = *impl_;
  if (m.o.webRoot.empty()) m.o.webRoot = assetsDir() + "/web";
  if (m.o.scenesDir.empty()) m.o.scenesDir = assetsDir() + "/scenes";
  std::error_code ec;
  if (!fs::is_regular_file(m.o.webRoot + "/index.html", ec))
    throw UsageError("--web " + m.o.webRoot + ": no index.html there (the page's folder is assets/web)");
  if (!fs::is_directory(m.o.scenesDir, ec)) throw UsageError("--scenes " + m.o.scenesDir + ": not a folder");
  if (!m.o.labDir.empty() && !fs::is_directory(m.o.labDir, ec)) throw UsageError("--lab " + m.o.labDir + ": not a folder");
  m.ffmpeg = findFfmpeg();
  std::string tmpl = (fs::temp_directory_path(ec) / "substep-serve-XXXXXX").string();
  if (!mkdtemp(tmpl.data())) throw std::runtime_error("cannot make a scratch folder for clips in " + fs::temp_directory_path(ec).string());
  m.scratch = tmpl;

  // Streams hold a thread each while they live: room for every session's stream, events and
  // requests at once.
  const size_t threads = static_cast<size_t>(4 * m.o.maxSessions + 16);
  m.http.new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
  m.http.set_payload_max_length(m.o.maxBody);
  // SO_REUSEADDR only: httplib's default adds SO_REUSEPORT, with which a second server on the
  // same port starts too and takes half the connections.
  m.http.set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  m.http.set_keep_alive_timeout(2);
  m.http.set_read_timeout(10);
  m.http.set_write_timeout(10);
  m.routesSetUp();
}

Server::~Server() {
  stop();
  std::error_code ec;
  fs::remove_all(impl_->scratch, ec);
}

int Server::bind() {
  Impl& m = *impl_;
  const int port = m.o.port == 0 ? m.http.bind_to_any_port(m.o.host) : (m.http.bind_to_port(m.o.host, m.o.port) ? m.o.port : -1);
  if (port <= 0)
    throw std::runtime_error("cannot listen on " + m.o.host + ":" + std::to_string(m.o.port) +
                             " (in use, or not an address of this machine)");
  m.reaper = std::thread([&m] { m.reap(); });
  return port;
}

void Server::listen() { impl_->http.listen_after_bind(); }

void Server::stop() {
  Impl& m = *impl_;
  if (m.stopping.exchange(true)) return;
  m.reaperCv.notify_all();
  if (m.reaper.joinable()) m.reaper.join();
  std::vector<std::shared_ptr<WebSession>> all;
  {
    std::lock_guard<std::mutex> lk(m.sessionsM);
    for (auto& [id, s] : m.sessions) all.push_back(s);
    m.sessions.clear();
  }
  for (auto& s : all) m.closeSession(s, "server stopping");
  m.http.stop();
}

}  // namespace substep::app

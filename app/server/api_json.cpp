// The JSON of `substep serve`'s answers: see api_json.h.
#include "app/server/api_json.h"

#include "app/common.h"
#include "app/server/http.h"
#include "app/server/requests.h"
#include "physics/settings_json.h"
#include "render/scene_builder.h"

#include <filesystem>

namespace substep::app::web {

using namespace substep::render;

json vec(const Vec3& v) { return json::array({v.x(), v.y(), v.z()}); }

// --- scenes, methods, the server --------------------------------------------------------------

json methodsJson() {
  json algos = json::array();
  for (Algorithm a : kAlgorithms) {
    SolverOverrides defaults;
    defaults.set(&SolverSettings::algorithm, a);
    algos.push_back({{"name", algorithmName(a)},
                     {"title", algorithmTitle(a)},
                     {"defaults", settingsJson(resolve(defaults))}});
  }
  return {{"algorithms", algos},
          {"settings", schemaJson()},
          {"colours", {"auto", "body", "group", "speed", "activity", "error"}},
          {"max_panels", kMaxPanels},
          {"example", "a5:n=4:kappa=0.85"}};
}

json sceneJson(const std::string& name, const Scene& s) {
  json cams = json::array();
  for (const CameraPreset& c : s.cameras) cams.push_back(c.name);
  json j = {{"name", name},
            {"description", s.description.substr(0, s.description.find('\n'))},
            {"bodies", s.model.dynamicCount()},
            {"joints", s.model.joints.size()},
            {"cameras", cams}};
  try {
    j["solver"] = (s.solver.empty() ? SolverOverrides{} : s.solver).specText();
    j["settings"] = settingsLine(resolveSettings(s, {}));
  } catch (const UsageError& e) {
    j["error"] = e.what();
  }
  return j;
}

json serverJson(const ServerOptions& o, size_t sessions, bool clips, bool lab) {
  return {{"sessions", sessions},
          {"max_sessions", o.maxSessions},
          {"size", std::to_string(o.width) + "x" + std::to_string(o.height)},
          {"fps", o.fps},
          {"idle_timeout", o.idleTimeout},
          {"history", o.history},
          {"clips", clips},
          {"lab", lab},
          {"open", [&] {
             json names = json::array();
             for (const std::string& p : o.open) names.push_back(std::filesystem::path(p).filename().string());
             return names;
           }()}};
}

// --- a session --------------------------------------------------------------------------------

json stateJson(WebSession& s) {
  std::lock_guard<std::mutex> lk(s.m);
  json j = s.live->read([&](const RenderSession& r, const Look& look) {
    json panels = json::array();
    for (int i = 0; i < r.panelCount(); ++i) {
      const Panel& p = r.panel(i);
      panels.push_back({{"method", s.panels[static_cast<size_t>(i)].method()},
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
                {"timeline", timelineJson(r)},
                {"selected", s.selected >= 0 ? json(s.scene->model.bodies[static_cast<size_t>(s.selected)].name) : json(nullptr)},
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
                  {"error_scale", look.view.errorScale},
                  {"forces", look.view.forces},
                  {"joint_errors", look.view.jointErrors},
                  {"force_scale", look.view.forceScale}}}};
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
                      {"ended", p.ended},
                      {"problem", p.problem}});
  return {{"seq", s.seq},          {"frames", s.frames},   {"playing", s.playing},     {"seeking", s.seeking},
          {"speed", s.speed},      {"achieved", s.achieved}, {"behind", s.behind},     {"fps", s.fps},
          {"physics_ms", s.physicsMs}, {"draw_ms", s.drawMs}, {"encode_ms", s.encodeMs}, {"jpeg_bytes", s.jpegBytes},
          {"frame_width", s.width}, {"frame_height", s.height}, {"size_note", s.sizeNote},
          {"status", s.status},    {"panels", panels},
          {"first", s.first},      {"last", s.last},       {"shown", s.shown},         {"shown_step", s.shownStep},
          {"live", s.live},        {"recorded", s.recorded}};
}

json clipJson(const ClipInfo& c, const std::string& sessionId) {
  json j = {{"id", c.id}, {"mode", c.mode}, {"seconds", c.seconds}, {"state", c.state}, {"frames", c.frames}};
  if (!c.error.empty()) j["error"] = validUtf8(c.error);  // ffmpeg's words, whatever bytes they are
  if (c.state == "done") {
    j["bytes"] = c.bytes;
    j["url"] = "/api/sessions/" + sessionId + "/clips/" + std::to_string(c.id) + ".mp4";
  }
  return j;
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

}  // namespace substep::app::web

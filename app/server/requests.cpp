// What the calls of `substep serve` ask for, read and checked: see requests.h.
#include "app/server/requests.h"

#include "physics/settings_json.h"

#include "app/common.h"
#include "app/render_options.h"
#include "app/server/api_json.h"

#include <cmath>

namespace substep::app::web {

using namespace substep::render;

namespace {

std::vector<MethodSpec> methodSpecs(const std::string& text, const std::string& field) {
  try {
    return parseMethodSpecs(text);
  } catch (const std::invalid_argument& e) {
    throw HttpError(400, field + ": " + e.what());
  }
}

}  // namespace

SolverOverrides methodOverrides(const std::string& text, const std::string& field) {
  const std::vector<MethodSpec> specs = methodSpecs(text, field);
  if (specs.size() != 1)
    throw HttpError(400, field + ": expected one method, e.g. a5:n=4:kappa=0.85 (panels take 1 to 4), got " +
                             std::to_string(specs.size()));
  return specs[0].overrides;
}

std::vector<WebSession::PanelState> panelsOf(const json& v, const std::string& field) {
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
  const std::vector<MethodSpec> specs = methodSpecs(text, field);
  if (specs.empty() || static_cast<int>(specs.size()) > kMaxPanels)
    throw HttpError(400, field + ": expected 1 to " + std::to_string(kMaxPanels) + " methods, got " +
                             std::to_string(specs.size()));
  std::vector<WebSession::PanelState> r;
  for (const MethodSpec& s : specs) r.push_back({s.overrides, {}});
  return r;
}

std::vector<WebSession::PanelState> newPanels(const Fields& f) {
  if (f.has("method") && f.has("methods")) throw HttpError(400, "method, methods: give one of them");
  if (f.has("method")) return {WebSession::PanelState{methodOverrides(f.text("method"), "method"), {}}};
  if (f.has("methods")) return panelsOf(f.at("methods"), "methods");
  return {WebSession::PanelState{}};
}

std::vector<int> panelTargets(const Fields& f, int count) {
  if (f.has("panel")) return {f.integer("panel", {0, static_cast<double>(count - 1)})};
  std::vector<int> all;
  for (int i = 0; i < count; ++i) all.push_back(i);
  return all;
}

std::string sceneName(const Fields& f) {
  if (!f.has("scene")) throw HttpError(400, "scene: expected a scene name (GET /api/scenes lists them)");
  return f.text("scene", 200);
}

std::vector<PanelSetup> setups(const Scene& scene, const std::vector<WebSession::PanelState>& panels, bool sleepByDefault) {
  const SettingSpec& sleep = settingOf(&SolverSettings::sleep);
  std::vector<PanelSetup> r;
  for (size_t i = 0; i < panels.size(); ++i) {
    SolverOverrides given = panels[i].user;
    if (sleepByDefault && !scene.solver.has(sleep) && !given.has(sleep)) given.set(sleep, 1);
    given = onEveryCore(scene, given);
    try {
      r.push_back({resolveSettings(scene, given), panels.size() > 1 ? panels[i].user.specText() : ""});
    } catch (const UsageError& e) {
      throw HttpError(400, (panels.size() > 1 ? "panel " + std::to_string(i) + ": " : std::string()) + e.what());
    }
  }
  return r;
}

void changeSettings(SolverOverrides& u, const json& set) {
  if (!set.is_object()) throw HttpError(400, "settings: expected an object of setting: value, got " + quote(set));
  // A new algorithm starts from its own defaults: n, κ, τ of another one may not apply.
  if (set.contains("algorithm") || set.contains("algo")) u = SolverOverrides{};
  for (const auto& [key, v] : set.items()) {
    const SettingSpec* spec = findSetting(key);
    const std::string name = "settings." + utf8Prefix(key, limits::kMaxMessageValue);
    if (!spec) throw HttpError(400, name + ": unknown setting; expected one of algorithm, " + settingKeys());
    try {
      if (v.is_null())
        u.clear(*spec);
      else if (v.is_string())
        u.setText(*spec, v.get<std::string>());  // numbers and flags as typed too: "1/120", "on"
      else
        u.set(*spec, settingFromJson(*spec, v));
    } catch (const std::invalid_argument& e) {
      throw HttpError(400, name + ": " + e.what());
    }
  }
}

void frameSize(const Fields& f, int& width, int& height) {
  const std::string size = f.text("size", 20);
  try {
    parseFrameSize(size, width, height);
  } catch (const UsageError&) {
    width = -1;
  }
  if (width < kMinSide || height < kMinSide || width > kMaxWidth || height > kMaxHeight)
    throw HttpError(400, "size: expected WIDTHxHEIGHT from " + std::to_string(kMinSide) + "x" + std::to_string(kMinSide) +
                             " to " + std::to_string(kMaxWidth) + "x" + std::to_string(kMaxHeight) + ", got " +
                             quote(json(size)));
}

std::pair<double, double> pixel(const Fields& f, int width, int height) {
  if (!f.has("x") || !f.has("y")) throw HttpError(400, "x, y: expected the pixel of the frame, e.g. {\"x\": 640, \"y\": 360}");
  return {f.number("x", {0, static_cast<double>(width), false, true}),
          f.number("y", {0, static_cast<double>(height), false, true})};
}

// --- camera ---

const std::vector<std::string> CameraChange::kFields = {"preset", "yaw",    "pitch",  "distance", "fov", "target",
                                                        "follow", "orbit", "rotate", "zoom",     "pan"};

CameraChange::CameraChange(const Fields& f) {
  if (f.has("preset")) preset = f.text("preset", limits::kMaxNameLength);
  if (f.has("follow")) follow = f.text("follow", limits::kMaxNameLength);
  if (f.has("yaw")) yaw = f.number("yaw", limits::kDegrees);
  if (f.has("pitch")) pitch = f.number("pitch", {-89, 89});
  if (f.has("distance")) distance = f.number("distance", limits::kDistance);
  if (f.has("fov")) fov = f.number("fov", {5, 150});
  if (f.has("orbit")) orbit = f.number("orbit", {-1e4, 1e4});
  if (f.has("zoom")) zoom = f.number("zoom", {0.01, 100});
  if (f.has("target")) target = f.vec3("target", limits::kCoordinate);
  if (f.has("rotate")) rotate = f.pair("rotate", {-360, 360});
  if (f.has("pan")) pan = f.pair("pan", {-1e4, 1e4});
}

void CameraChange::checkFollow(const Scene& sc, const std::string& sceneName) const {
  if (!follow || follow->empty()) return;
  const int b = sc.model.bodyIndex(*follow);
  if (b < 0 || sc.model.bodies[static_cast<size_t>(b)].isStatic)
    throw HttpError(400, "follow: expected the name of a dynamic body of " + sceneName + ", or \"\" for none, got " +
                             quote(json(*follow)));
}

void CameraChange::apply(Look& look, const std::optional<CameraPreset>& chosen, const Model& model, const State& state,
                         int height) const {
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
    const Camera cam = placeCamera(c, model, state, look.orbit);
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
}

// --- view ---

const std::vector<std::string> ViewChange::kFields = {"colour",      "color",       "contacts",     "joints",
                                                      "hud",         "speed_scale", "error_scale",  "highlight",
                                                      "forces",      "joint_errors", "force_scale"};

ViewChange::ViewChange(const Fields& f) {
  for (const char* k : {"colour", "color"})
    if (f.has(k)) {
      colour = parseColourMode(f.text(k, 40));
      if (!colour)
        throw HttpError(400, std::string(k) + ": expected auto, body, group, speed, activity or error, got " + quote(f.at(k)));
    }
  if (f.has("speed_scale")) speedScale = f.number("speed_scale", {1e-9, 1e9});
  if (f.has("error_scale")) errorScale = f.number("error_scale", {1e-12, 1e9});
  if (f.has("contacts")) contacts = f.flag("contacts");
  if (f.has("joints")) joints = f.flag("joints");
  if (f.has("hud")) hud = f.flag("hud");
  if (f.has("forces")) forces = f.flag("forces");
  if (f.has("joint_errors")) jointErrors = f.flag("joint_errors");
  if (f.has("force_scale")) forceScale = f.number("force_scale", {0, 1e9});  // 0: automatic
}

void ViewChange::readHighlight(const Fields& f, const Scene& scene, const std::string& sceneName) {
  if (!f.has("highlight")) return;
  const json& h = f.at("highlight");
  if (!h.is_array()) throw HttpError(400, "highlight: expected a list of body names, got " + quote(h));
  highlight.emplace();
  for (const json& x : h) {
    if (!x.is_string() || scene.model.bodyIndex(x.get<std::string>()) < 0)
      throw HttpError(400, "highlight: expected names of bodies of " + sceneName + ", got " + quote(x));
    highlight->push_back(x.get<std::string>());
  }
}

void ViewChange::apply(Look& look) const {
  if (colour) look.view.colour = *colour;
  if (contacts) look.view.contacts = *contacts;
  if (joints) look.view.joints = *joints;
  if (hud) look.view.hud = *hud;
  if (speedScale) look.view.speedScale = *speedScale;
  if (errorScale) look.view.errorScale = *errorScale;
  if (forces) look.view.forces = *forces;
  if (jointErrors) look.view.jointErrors = *jointErrors;
  if (forceScale) look.view.forceScale = *forceScale;
  if (highlight) look.view.highlight = *highlight;
}

}  // namespace substep::app::web

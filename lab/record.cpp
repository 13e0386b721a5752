#include "lab/record.h"

#include "lab/peers.h"
#include "lab/provenance.h"
#include "physics/recording.h"
#include "physics/settings_json.h"
#include "physics/state_hash.h"

#include <cstdio>

#include <cctype>
#include <cmath>
#include <filesystem>

namespace substep::lab {

namespace {

using json = nlohmann::json;

json number(double x) { return std::isfinite(x) ? json(x) : json(nullptr); }
json optional(const std::optional<double>& x) { return x ? number(*x) : json(nullptr); }

json metricsJson(const Metrics& m) {
  json byKind = json::object();
  for (const auto& [kind, k] : m.byKind)
    byKind[kind] = {{"max_m", k.max}, {"rms_m", k.rms}, {"angle_max_rad", k.angleMax}};
  const FailureReport& f = m.failure;
  auto time = [](double t) { return t < 0 ? json(nullptr) : json(t); };
  return {
      {"penetration_max_m", m.penetrationMax},
      {"penetration_rms_m", m.penetrationRms},
      {"penetration_end_m", m.penetrationEnd},
      {"joint_error_max_m", m.joints ? json(m.jointErrorMax) : json(nullptr)},
      {"joint_error_rms_m", m.joints ? json(m.jointErrorRms) : json(nullptr)},
      {"joint_angle_error_max_rad", m.joints ? json(m.jointAngleErrorMax) : json(nullptr)},
      {"joint_error_by_kind", byKind},
      {"limit_excess_rad",
       {{"max", m.limitExcess.max()}, {"hinge", m.limitExcess.hinge}, {"swing", m.limitExcess.swing}, {"twist", m.limitExcess.twist}}},
      {"energy_start_J", number(m.energyStart)},
      {"energy_end_J", number(m.energyEnd)},
      {"energy_drift", optional(m.energyDrift)},
      {"energy_drift_end", optional(m.energyDriftEnd)},
      {"linear_momentum_drift", optional(m.linearMomentumDrift)},
      {"angular_momentum_drift", optional(m.angularMomentumDrift)},
      {"jitter_mps", m.jitter},
      {"displacement_max_m", m.displacementMax},
      {"displacement_body", m.displacementBody},
      {"sideways_max_m", m.sidewaysMax},
      {"sideways_body", m.sidewaysBody},
      {"collapse_time_s", optional(m.collapseTime)},
      {"collapse_rule", m.collapseRule},
      {"speed_max_mps", m.speedMax},
      {"failure",
       {{"verdict", f.verdict()}, {"sag_time_s", time(f.sagTime)}, {"collapse_time_s", time(f.collapseTime)},
        {"diverge_time_s", time(f.divergeTime)}, {"max_sag_m", f.maxSag}, {"max_sideways_m", f.maxSideways},
        {"max_energy_gain_J", number(f.maxEnergyGain)}}},
      {"trajectory_error_m", optional(m.trajectoryError)},
      {"trajectory_error_rms_m", optional(m.trajectoryErrorRms)},
      {"reference_error", optional(m.referenceError)},
      {"reference", m.referenceText},
      {"period_s", optional(m.periodMeasured)},
      {"period_reference_s", optional(m.periodReference)},
      {"moving_least_m", optional(m.movingLeast)},
      {"stayed_in", m.stayedIn ? json(*m.stayedIn) : json(nullptr)},
      {"turned_most_rad", optional(m.turnedMost)},
  };
}

}  // namespace

json recordSettingsJson(const Method& m, const SolverSettings& s) {
  if (m.isPeer()) return peerSettingsJson(peerSettings(m, s));
  return settingsJson(s);
}

json hashesJson(const RunHashes& h) {
  json steps = json::array(), bodies = json::array();
  for (const auto& [k, v] : h.steps) steps.push_back(json::array({k, hashText(v)}));
  for (const auto& [k, v] : h.bodies) {
    std::string hex;
    hex.reserve(8 * v.size());
    char buf[9];
    for (uint32_t x : v) {
      std::snprintf(buf, sizeof buf, "%08x", x);
      hex += buf;
    }
    bodies.push_back({{"step", k}, {"hashes", hex}});
  }
  return {{"every", h.every}, {"steps", steps}, {"bodies", bodies}, {"dynamic_bodies", h.dynamic.size()}};
}

RunHashes hashesFromJson(const json& j) {
  auto bad = [](const std::string& what) { return std::invalid_argument("state_hashes: " + what); };
  if (!j.is_object() || !j.contains("every") || !j.contains("steps") || !j.contains("bodies"))
    throw bad("expected an object with every, steps and bodies");
  RunHashes h;
  h.every = j["every"].get<long long>();
  for (const json& x : j["steps"]) {
    if (!x.is_array() || x.size() != 2 || !x[0].is_number_integer() || !x[1].is_string()) throw bad("expected [step, \"hash\"] pairs");
    const std::optional<uint64_t> v = parseHash(x[1].get<std::string>());
    if (!v) throw bad("\"" + x[1].get<std::string>() + "\" is not a hash of 16 hex digits");
    h.steps.emplace_back(x[0].get<long long>(), *v);
  }
  for (const json& x : j["bodies"]) {
    if (!x.is_object() || !x.contains("step") || !x.contains("hashes") || !x["hashes"].is_string())
      throw bad("expected {step, hashes} objects in bodies");
    const std::string hex = x["hashes"].get<std::string>();
    if (hex.size() % 8 != 0 || hex.find_first_not_of("0123456789abcdef") != std::string::npos)
      throw bad("body hashes: expected 8 hex digits a body");
    std::vector<uint32_t> v;
    for (size_t i = 0; i < hex.size(); i += 8) v.push_back(static_cast<uint32_t>(std::stoul(hex.substr(i, 8), nullptr, 16)));
    h.bodies.emplace_back(x["step"].get<long long>(), std::move(v));
  }
  return h;
}

void addReproduction(json& j, const Scene& scene, const std::string& engine, const json& settings, long long steps, long long stepsDone,
                     const RunHashes& hashes) {
  std::error_code ec;
  j["scene_file"] = scene.file;
  j["scene_path"] = std::filesystem::absolute(scene.file, ec).lexically_normal().string();
  j["scene_hash"] = scene.hash;
  j["engine"] = engine;
  j["settings"] = settings;
  j["steps"] = steps;
  j["steps_done"] = stepsDone;
  j["commit"] = sourceCommit();
  j["source"] = sourceState();
  // The threads the steps ran on (a peer's: one); the trajectory does not depend on it.
  j["threads"] = settings.is_object() && settings.contains("threads") ? settings["threads"] : json(1);
  j["state_hash"] = hashText(hashes.last);
  j["state_hashes"] = hashesJson(hashes);
}

json recordingMeta(const Scene& scene, const std::vector<RecordingPanel>& panels, long long every, long long plannedSteps) {
  std::error_code ec;
  json j;
  j["format"] = "substep-recording";
  j["version"] = kRecordingVersion;
  j["scene"] = {{"file", scene.file},
                {"base_dir", std::filesystem::absolute(scene.baseDir.empty() ? "." : scene.baseDir, ec).lexically_normal().string()},
                {"text", scene.text}};
  j["bodies"] = scene.model.bodies.size();
  j["joints"] = scene.model.joints.size();
  json ps = json::array();
  for (const RecordingPanel& p : panels) {
    json x = {{"name", p.name}, {"settings", p.settings}, {"engine", p.engine}};
    if (!p.method.empty()) x["method"] = p.method;
    ps.push_back(x);
  }
  j["panels"] = ps;
  j["every"] = every;
  j["planned_steps"] = plannedSteps;
  j["created_utc"] = utcNow();
  const RecordingPanel first = panels.empty() ? RecordingPanel{} : panels.front();
  addReproduction(j, scene, first.engine, first.settings, plannedSteps, 0, RunHashes{});
  for (const char* k : {"steps_done", "state_hash", "state_hashes"}) j.erase(k);
  return j;
}

std::string recordingFileName(const Scene& scene, const std::string& method, const std::optional<double>& dt) {
  auto safe = [](std::string s) {
    for (char& c : s)
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '=' && c != '_' && c != '-') c = '_';
    return s;
  };
  return safe(sceneName(scene)) + "-" + safe(method) + (dt ? "-h" + safe(stepText(*dt)) : "") + ".rec";
}

std::optional<std::string> statedErrorMetric(const Scene& scene) {
  if (!scene.criteria) return std::nullopt;
  const SceneCriteria& c = *scene.criteria;
  if (!c.error.empty()) return c.error;
  if (!c.pass.empty()) return c.pass.front().first;
  if (c.reference) return c.reference->kind == SceneReference::Kind::TorqueFree ? "reference_error" : "trajectory_error";
  return std::nullopt;
}

std::string errorMetric(const Scene& scene) {
  return statedErrorMetric(scene).value_or(scene.model.joints.empty() ? "penetration" : "joint_error");
}

std::string runKey(const Scene& scene, const std::string& method, double dt, double seconds) {
  std::string key = sceneName(scene) + " | " + method + " | h=" + stepText(dt) + " | " + numberText(seconds) + " s";
  if (scene.criteria && scene.criteria->reference) {
    const SceneReference& r = *scene.criteria->reference;
    key += std::string(" | against ") + referenceKindName(r.kind) + (r.method.empty() ? "" : " " + r.method);
  }
  return key;
}

std::string sceneName(const Scene& scene) { return std::filesystem::path(scene.file).stem().string(); }

json recordJson(const Scene& scene, const RunResult& run, double seconds, int repeat, const std::optional<SweepPlace>& place) {
  const std::string name = sceneName(scene);
  json j;
  j["key"] = runKey(scene, run.method.text, run.settings.dt, seconds);
  j["scene"] = name;
  j["method"] = run.method.text;
  j["family"] = run.method.family();
  j["h"] = stepText(run.settings.dt);
  addReproduction(j, scene, run.method.isPeer() ? run.method.peer : "substep", recordSettingsJson(run.method, run.settings), run.steps, run.stepsDone,
                  run.hashes);
  j["seconds"] = seconds;
  j["time_s"] = run.time;
  j["repeat"] = repeat;
  j["finite"] = run.finite;
  j["diverged"] = run.diverged;
  j["refused"] = run.refused;
  j["stopped"] = run.stopped.empty() ? json(nullptr) : json(run.stopped);
  j["stopped_early"] = run.stoppedEarly.empty() ? json(nullptr) : json(run.stoppedEarly);
  json stages = nullptr;
  if (run.cost.stages)
    stages = {{"s1", run.cost.stages->s1}, {"s2", run.cost.stages->s2}, {"s3", run.cost.stages->s3}, {"s4", run.cost.stages->s4}};
  j["cost"] = {{"ms_per_step", run.cost.msPerStep},
               {"ms_per_second", run.msPerSecond()},
               {"stages_ms_per_step", stages},
               {"repeats_ms_per_step", run.cost.repeats}};
  j["metrics"] = metricsJson(run.metrics);
  json values = json::object();
  if (!run.refused)
    for (const std::string& m : criterionMetrics())
      if (const auto v = metricValue(run.metrics, m)) values[m] = number(*v);
  j["values"] = values;
  const std::string error = errorMetric(scene);
  j["error"] = {{"metric", error}, {"label", metricLabel(error)}, {"unit", metricUnit(error)},
                {"value", run.refused ? json(nullptr) : optional(metricValue(run.metrics, error))}};
  if (const Verdict v = judge(scene, run); v.result != Verdict::Result::NoCriteria) {
    json checks = json::array();
    for (const Check& c : v.checks) checks.push_back({{"check", c.text}, {"ok", c.ok}});
    j["verdict"] = {{"result", resultName(v.result)}, {"figure", v.figure}, {"checks", checks}};
  }
  if (place) j["sweep"] = {{"plan", place->plan}, {"index", place->index}, {"runs", place->runs}};
  j["recording"] = run.recording.empty() ? json(nullptr) : json(run.recording);
  return j;
}

std::optional<double> recordValue(const json& row, const std::string& metric) {
  const auto v = row.find("values");
  if (v == row.end() || !v->is_object()) return std::nullopt;
  const auto x = v->find(metric);
  if (x == v->end() || !x->is_number()) return std::nullopt;
  return x->get<double>();
}

}  // namespace substep::lab

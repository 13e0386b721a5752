#include "lab/record.h"

#include "lab/provenance.h"
#include "physics/settings_json.h"

#include <cmath>
#include <filesystem>

namespace substep::lab {

namespace {

using json = nlohmann::json;

json number(double x) { return std::isfinite(x) ? json(x) : json(nullptr); }
json optional(const std::optional<double>& x) { return x ? number(*x) : json(nullptr); }

// Every setting the run used (physics/settings_json.h); the Bullet peer's are the three it maps.
json runSettingsJson(const Method& m, const SolverSettings& s) {
  json j = substep::settingsJson(s);
  if (m.isBullet())
    j = {{"dt", s.dt}, {"iterations", s.iterations}, {"gyroscopic", s.gyroscopic == Gyroscopic::None ? "none" : "implicit"}};
  j["h"] = stepText(s.dt);
  return j;
}

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

std::string errorMetric(const Scene& scene) {
  if (scene.criteria && !scene.criteria->error.empty()) return scene.criteria->error;
  if (scene.criteria && !scene.criteria->pass.empty()) return scene.criteria->pass.front().first;
  if (scene.criteria && scene.criteria->reference) {
    const auto k = scene.criteria->reference->kind;
    return k == SceneReference::Kind::TorqueFree ? "reference_error" : "trajectory_error";
  }
  return scene.model.joints.empty() ? "penetration" : "joint_error";
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
  j["scene_file"] = scene.file;
  j["method"] = run.method.text;
  j["family"] = run.method.family();
  j["engine"] = run.method.isBullet() ? "bullet" : "substep";
  j["settings"] = runSettingsJson(run.method, run.settings);
  j["seconds"] = seconds;
  j["steps"] = run.steps;
  j["steps_done"] = run.stepsDone;
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
  j["commit"] = sourceCommit();
  if (place) j["sweep"] = {{"plan", place->plan}, {"index", place->index}, {"runs", place->runs}};
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

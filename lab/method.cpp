#include "lab/method.h"

#include <cmath>
#include <stdexcept>

namespace substep::lab {

std::string Method::family() const {
  if (!peer.empty()) return peer;
  return overrides.algorithm ? algorithmName(*overrides.algorithm) : "?";
}

std::vector<Method> parseMethods(const std::string& list) {
  std::vector<Method> out;
  for (const MethodSpec& s : parseMethodSpecs(list)) out.push_back(Method{s.text, s.overrides, s.peer});
  return out;
}

SolverSettings methodSettings(const Method& m, const Scene& scene, std::optional<double> dt) {
  SolverOverrides o;
  o.dt = dt ? dt : scene.solver.dt;
  if (scene.criteria) o = o.merged(scene.criteria->with);
  SolverOverrides own = m.overrides;
  if (m.isBullet()) {
    // Only what the peer maps; the algorithm stays A2 so that resolve() leaves n at 1.
    own.algorithm = Algorithm::A2;
    if (!own.iterations) own.iterations = 10;
    if (!own.gyroscopic && !o.gyroscopic) own.gyroscopic = "implicit";  // Bullet's own default
  }
  o = o.merged(own);
  return resolve(o);
}

BulletSettings bulletSettings(const Method& m, const Scene& scene, std::optional<double> dt) {
  const SolverSettings s = methodSettings(m, scene, dt);
  return BulletSettings{s.dt, s.iterations, s.gyroscopic != Gyroscopic::None};
}

std::vector<SettingValue> settingValues(const Method& m, const SolverSettings& s) {
  // The resolved settings as overrides, printed by the table, so that every key is the table's.
  SolverOverrides o;
  o.algorithm = s.algorithm;
  o.dt = s.dt;
  o.substeps = s.substeps;
  o.iterations = s.iterations;
  o.omega = s.omega;
  o.tolerance = s.tolerance;
  o.kappa = s.kappa;
  o.tau = s.tau;
  o.slop = s.slop;
  o.warmStart = s.warmStart;
  o.blockSolve = s.blockSolve;
  o.splitImpulse = s.splitImpulse;
  o.contactBlocks = s.contactBlocks;
  o.motorUnscaled = s.motorUnscaled;
  o.frictionExempt = s.frictionExempt;
  o.speculative = s.speculative;
  o.restitution = s.restitution;
  o.islands = s.islands;
  o.restitutionThreshold = s.restitutionThreshold;
  o.jacobians = s.jacobians == JacobianRefresh::Stable ? "stable" : "joints";
  o.gyroscopic = s.gyroscopic == Gyroscopic::Implicit ? "implicit" : s.gyroscopic == Gyroscopic::Explicit ? "explicit" : "none";
  o.contactHertz = s.contactHertz;
  o.contactDamping = s.contactDamping;
  o.jointHertz = s.jointHertz;
  o.jointDamping = s.jointDamping;
  o.pushOut = s.pushOut;
  std::vector<SettingValue> out;
  for (const SettingSpec& spec : settingTable()) {
    const std::string key = spec.key;
    if (m.isBullet() && key != "dt" && key != "iterations" && key != "gyroscopic") continue;
    if (m.isBullet() && key == "gyroscopic") {
      out.push_back({key, s.gyroscopic == Gyroscopic::None ? "none" : "implicit"});
      continue;
    }
    if (spec.isSet(o)) out.push_back({key, spec.valueText(o)});
  }
  return out;
}

std::string stepText(double dt) {
  const double inv = 1.0 / dt;
  if (std::abs(inv - std::round(inv)) < 1e-9 * inv) return "1/" + std::to_string(std::llround(inv));
  return numberText(dt);
}

}  // namespace substep::lab

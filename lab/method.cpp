#include "lab/method.h"

#include <cmath>
#include <stdexcept>

namespace substep::lab {

std::string Method::family() const {
  if (!peer.empty()) return peer;
  return overrides.algorithm() ? algorithmName(*overrides.algorithm()) : "?";
}

std::vector<Method> parseMethods(const std::string& list) {
  std::vector<Method> out;
  for (const MethodSpec& s : parseMethodSpecs(list)) out.push_back(Method{s.text, s.overrides, s.peer, s.peerOptions});
  return out;
}

SolverSettings methodSettings(const Method& m, const Scene& scene, std::optional<double> dt) {
  using S = SolverSettings;
  SolverOverrides o;
  if (const std::optional<double> h = dt ? dt : scene.solver.get(&S::dt)) o.set(&S::dt, *h);
  if (scene.criteria) o = o.merged(scene.criteria->with);
  SolverOverrides own = m.overrides;
  if (m.isPeer()) {
    // Only what the peer maps; the algorithm stays A2 so that resolve() leaves n at 1.
    const PeerSpec& p = *findPeer(m.peer);
    own.set(&S::algorithm, Algorithm::A2);
    if (!own.get(&S::iterations)) own.set(&S::iterations, p.iterations);
    if (!own.get(&S::gyroscopic) && !o.get(&S::gyroscopic)) own.set(&S::gyroscopic, Gyroscopic::Implicit);  // Bullet's and ODE's own
  }
  return resolve(o.merged(own));
}

BulletSettings bulletSettings(const Method& m, const Scene& scene, std::optional<double> dt) {
  const SolverSettings s = methodSettings(m, scene, dt);
  return BulletSettings{s.dt, s.iterations, s.gyroscopic != Gyroscopic::None};
}

PeerOptions peerOptions(const Method& m) {
  PeerOptions out;
  if (!m.isPeer()) return out;
  for (const SettingSpec& s : findPeer(m.peer)->own) {
    const auto it = m.peerOptions.find(s.key);
    out[s.key] = it != m.peerOptions.end() ? it->second : s.defaultFor(Algorithm::A2);
  }
  return out;
}

}  // namespace substep::lab

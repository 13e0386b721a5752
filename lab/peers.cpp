#include "lab/peers.h"

#include "lab/bullet_peer.h"
#include "lab/mujoco_peer.h"
#include "lab/ode_peer.h"

#include <stdexcept>

namespace substep::lab {

using json = nlohmann::json;

namespace {

const PeerSpec& specOf(const std::string& peer) {
  const PeerSpec* p = findPeer(peer);
  if (!p) throw std::invalid_argument("unknown peer \"" + peer + "\"");
  return *p;
}

bool takesGyroscopic(const PeerSpec& p) {
  for (const std::string& k : p.tableKeys)
    if (k == "gyroscopic") return true;
  return false;
}

}  // namespace

double PeerSettings::option(const std::string& key) const {
  const auto it = options.find(key);
  if (it == options.end()) throw std::logic_error("the " + peer + " peer's settings lack " + key);
  return it->second;
}

std::string PeerSettings::optionText(const std::string& key) const { return specOf(peer).findOwn(key)->text(option(key)); }

PeerSettings peerSettings(const Method& m, const SolverSettings& resolved) {
  PeerSettings s;
  s.peer = m.peer;
  s.dt = resolved.dt;
  s.iterations = resolved.iterations;
  s.gyroscopic = resolved.gyroscopic;
  s.options = peerOptions(m);
  return s;
}

std::string peerUnsupported(const std::string& peer, const Model& model, const State& initial) {
  if (peer == kBulletPeer) return bulletUnsupported(model);
  if (peer == kOdePeer) return odeUnsupported(model, initial);
  if (peer == kMujocoPeer) return mujocoUnsupported(model, initial);
  throw std::invalid_argument("unknown peer \"" + peer + "\"");
}

std::string peerDisplayName(const std::string& peer) { return specOf(peer).engine; }

std::string peerVersion(const std::string& peer) {
  if (peer == kBulletPeer) return bulletVersion();
  if (peer == kOdePeer) return odeVersion();
  if (peer == kMujocoPeer) return mujocoVersion();
  throw std::invalid_argument("unknown peer \"" + peer + "\"");
}

std::unique_ptr<Engine> makePeerEngine(const PeerSettings& s, const Model& model, const State& initial) {
  if (s.peer == kBulletPeer)
    return std::make_unique<BulletEngine>(model, initial, s.dt, s.iterations, s.gyroscopic != Gyroscopic::None);
  if (s.peer == kOdePeer) {
    OdeSettings o;
    o.dt = s.dt;
    o.iterations = s.iterations;
    o.sor = s.option("sor");
    o.quick = s.optionText("step") == "quick";
    o.erp = s.option("erp");
    o.cfm = s.option("cfm");
    o.layer = s.option("layer");
    o.gyroscopic = s.gyroscopic != Gyroscopic::None;
    return makeOdeEngine(model, initial, o);
  }
  if (s.peer == kMujocoPeer) {
    MujocoSettings o;
    o.dt = s.dt;
    o.iterations = s.iterations;
    o.solver = static_cast<int>(s.option("solver"));
    o.integrator = static_cast<int>(s.option("integrator"));
    o.elliptic = s.optionText("cone") == "elliptic";
    o.margin = s.option("margin");
    return makeMujocoEngine(model, initial, o);
  }
  throw std::invalid_argument("unknown peer \"" + s.peer + "\"");
}

json peerSettingsJson(const PeerSettings& s) {
  const PeerSpec& p = specOf(s.peer);
  json j = {{"dt", s.dt}, {"iterations", s.iterations}};
  // Bullet and ODE have their own gyroscopic term, on or off: "implicit" names it on.
  if (takesGyroscopic(p)) j["gyroscopic"] = s.gyroscopic == Gyroscopic::None ? "none" : "implicit";
  for (const SettingSpec& o : p.own) {
    const double v = s.option(o.key);
    if (o.kind == SettingKind::Choice || o.kind == SettingKind::Flag)
      j[o.key] = o.text(v);
    else
      j[o.key] = v;
  }
  return j;
}

PeerSettings peerSettingsFromJson(const std::string& peer, const json& j, const std::string& where) {
  const PeerSpec& p = specOf(peer);
  if (!j.is_object()) throw std::invalid_argument(where + ": expected an object of the " + peer + " peer's settings");
  auto need = [&](const char* key) -> const json& {
    if (!j.contains(key)) throw std::invalid_argument(where + ": the " + peer + " peer's settings need " + key);
    return j.at(key);
  };
  PeerSettings s;
  s.peer = peer;
  if (!need("dt").is_number() || !(j["dt"].get<double>() > 0))
    throw std::invalid_argument(where + ".dt: expected a time step > 0");
  s.dt = j["dt"].get<double>();
  if (!need("iterations").is_number_integer() || j["iterations"].get<long long>() < 1)
    throw std::invalid_argument(where + ".iterations: expected an integer >= 1");
  s.iterations = j["iterations"].get<int>();
  if (takesGyroscopic(p)) {
    const json& g = need("gyroscopic");
    if (!g.is_string() || (g != "none" && g != "implicit"))
      throw std::invalid_argument(where + ".gyroscopic: expected \"none\" or \"implicit\"");
    s.gyroscopic = g == "none" ? Gyroscopic::None : Gyroscopic::Implicit;
  }
  for (const SettingSpec& o : p.own) {
    const json& v = need(o.key);
    try {
      if (v.is_string())
        s.options[o.key] = o.parse(v.get<std::string>());
      else if (v.is_number())
        s.options[o.key] = o.check(v.get<double>());
      else
        throw std::invalid_argument("expected " + o.expected());
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(where + "." + o.key + ": " + e.what());
    }
  }
  return s;
}

std::string peerLine(const PeerSettings& s) {
  const PeerSpec& p = specOf(s.peer);
  std::string line = s.peer + " it=" + std::to_string(s.iterations) + " h=" + stepText(s.dt);
  if (takesGyroscopic(p)) line += std::string(" gyro=") + (s.gyroscopic == Gyroscopic::None ? "none" : "on");
  for (const SettingSpec& o : p.own) line += " " + std::string(o.key) + "=" + s.optionText(o.key);
  return line;
}

}  // namespace substep::lab

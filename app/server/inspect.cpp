#include "app/server/inspect.h"

#include "app/server/api_json.h"
#include "physics/failure.h"

#include <algorithm>
#include <limits>

namespace substep::app::web {

using render::Panel;
using render::RenderSession;

namespace {

json vecf(const Eigen::Vector3f& v) { return json::array({v.x(), v.y(), v.z()}); }

// A live run has no planned end: its metrics of "the second half" wait for one that never comes.
constexpr double kLiveSeconds = 1e9;

}  // namespace

json markerJson(int panel, const lab::TimelineMarker& m, const Model& model) {
  return {{"panel", panel},
          {"kind", m.kind},
          {"step", m.step},
          {"time", m.time},
          {"body", m.body >= 0 ? json(model.bodies[static_cast<size_t>(m.body)].name) : json(nullptr)},
          {"value", m.value},
          {"text", m.text}};
}

namespace {

json shapeJson(const Shape& s) {
  json j = {{"type", shapeTypeName(s.type)}};
  switch (s.type) {
    case ShapeType::Box: j["half_extents"] = vec(s.halfExtents); break;
    case ShapeType::Sphere: j["radius"] = s.radius; break;
    case ShapeType::Capsule:
    case ShapeType::Cylinder:
      j["radius"] = s.radius;
      j["half_height"] = s.halfHeight;
      break;
    default:
      if (s.mesh) j["scale"] = s.scale;
  }
  return j;
}

}  // namespace

RenderSession::SnapshotHook SessionTimeline::hook() {
  return [this](int panel, const std::shared_ptr<const Scene>& scene, const Snapshot& s) {
    std::lock_guard<std::mutex> lk(m_);
    if (static_cast<size_t>(panel) >= panels_.size()) panels_.resize(static_cast<size_t>(panel) + 1);
    Watch& w = panels_[static_cast<size_t>(panel)];
    // A panel's first snapshot (t = 0: a new panel, a restart) starts its markers afresh.
    if (!w.watch || s.state.step == 0 || w.scene != scene) {
      w.scene = scene;
      w.watch = std::make_unique<lab::TimelineWatch>(*scene, seconds_ > 0 ? seconds_ : kLiveSeconds);
    }
    w.watch->add(s);
  };
}

json SessionTimeline::markersJson(const RenderSession& r) const {
  std::vector<std::pair<double, json>> all;
  {
    std::lock_guard<std::mutex> lk(m_);
    for (size_t i = 0; i < panels_.size() && static_cast<int>(i) < r.panelCount(); ++i)
      if (panels_[i].watch)
        for (const lab::TimelineMarker& m : panels_[i].watch->markers())
          all.emplace_back(m.time, markerJson(static_cast<int>(i), m, panels_[i].scene->model));
  }
  for (int i = 0; i < r.panelCount(); ++i) {
    const Panel& p = r.panel(i);
    if (!p.diverged()) continue;
    all.emplace_back(p.divergedAt(), json{{"panel", i}, {"kind", p.refused() ? "refused" : "diverged"},
                                           {"step", p.world().state().step}, {"time", p.divergedAt()},
                                           {"body", nullptr}, {"value", 0}, {"text", p.problem()}});
  }
  std::stable_sort(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  json out = json::array();
  for (auto& [t, j] : all) out.push_back(std::move(j));
  return out;
}

std::optional<std::pair<int, lab::TimelineMarker>> SessionTimeline::worst(const std::string& kind, int panel) const {
  std::lock_guard<std::mutex> lk(m_);
  std::optional<std::pair<int, lab::TimelineMarker>> best;
  for (size_t i = 0; i < panels_.size(); ++i) {
    if ((panel >= 0 && static_cast<int>(i) != panel) || !panels_[i].watch) continue;
    const auto m = panels_[i].watch->worst(kind);
    if (m && (!best || m->value > best->second.value)) best.emplace(static_cast<int>(i), *m);
  }
  return best;
}

json timelineJson(const RenderSession& r) {
  const Panel& p = r.panel(0);
  return {{"first", r.firstKept()},  {"last", r.lastKept()}, {"shown", r.time()},
          {"shown_step", p.state().step}, {"live", r.live()}, {"recorded", r.recorded()},
          {"dt", p.settings().dt},    {"kept", p.history().size()}};
}

json inspectJson(const RenderSession& r, const std::vector<std::string>& methods, int body) {
  const Model& model = r.scene().model;
  if (body < 0 || static_cast<size_t>(body) >= model.bodies.size()) return {{"body", nullptr}, {"panels", json::array()}};
  const Body& B = model.bodies[static_cast<size_t>(body)];
  auto name = [&](int i) { return model.bodies[static_cast<size_t>(i)].name; };
  json panels = json::array();
  for (int i = 0; i < r.panelCount(); ++i) {
    const Snapshot& s = r.panel(i).shown();
    const BodyState& b = s.state.bodies[static_cast<size_t>(body)];
    const Vec3 w = b.worldAngularVelocity();
    const double kinetic = B.isStatic ? 0.0 : kineticEnergy(B, b);
    json contacts = json::array();
    for (const ManifoldSnap& m : s.manifolds) {
      if (m.a != body && m.b != body) continue;
      // As the selected body has them: the normal pointing into it, the friction impulse on it.
      const float sign = m.a == body ? 1.0f : -1.0f;
      for (int k = m.first; k < m.first + m.count; ++k) {
        const ContactSnap& c = s.contacts[static_cast<size_t>(k)];
        contacts.push_back({{"other", name(m.a == body ? m.b : m.a)},
                            {"point", vecf(c.point)},
                            {"normal", vecf(sign * c.normal)},
                            {"depth", c.depth},
                            {"normal_impulse", c.normalImpulse},
                            {"friction", vecf(sign * m.friction)},
                            {"twist", sign * m.twist}});
      }
    }
    json joints = json::array();
    for (size_t k = 0; k < model.joints.size() && k < s.joints.size(); ++k) {
      const Joint& j = model.joints[k];
      if (j.bodyA != body && j.bodyB != body) continue;
      const JointSnap& js = s.joints[k];
      joints.push_back({{"name", j.name},
                        {"kind", jointTypeName(j.type)},
                        {"other", name(j.bodyA == body ? j.bodyB : j.bodyA)},
                        {"error", js.error},
                        {"impulse_on", name(j.bodyA)},  // the rows' impulse on body A (B takes the opposite force)
                        {"linear_impulse", vecf(js.linear)},
                        {"angular_impulse", vecf(js.angular)}});
    }
    panels.push_back({{"panel", i},
                      {"method", i < static_cast<int>(methods.size()) ? methods[static_cast<size_t>(i)] : ""},
                      {"time", s.state.time},
                      {"step", s.state.step},
                      {"name", B.name},
                      {"shape", shapeJson(B.shape)},
                      {"static", B.isStatic},
                      {"mass", B.mass},
                      {"inertia", vec(B.inertia)},
                      {"position", vec(b.x)},
                      {"orientation", json::array({b.q.w(), b.q.x(), b.q.y(), b.q.z()})},
                      {"velocity", vec(b.v)},
                      {"angular_velocity", vec(w)},
                      {"kinetic", kinetic},
                      {"contacts", contacts},
                      {"joints", joints}});
  }
  return {{"body", B.name}, {"panels", panels}};
}

}  // namespace substep::app::web

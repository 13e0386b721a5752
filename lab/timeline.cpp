#include "lab/timeline.h"

#include "lab/verdict.h"

#include <cmath>
#include <cstdio>

namespace substep::lab {

namespace {

std::string lengthText(const char* what, double metres) { return std::string(what) + " " + formatLength(metres); }

}  // namespace

TimelineWatch::TimelineWatch(const Scene& scene, double seconds) : scene_(scene), probe_(scene, seconds) {
  if (scene.criteria) failed_.resize(scene.criteria->pass.size());
  open_ = static_cast<int>(failed_.size());
}

void TimelineWatch::add(const Snapshot& s) {
  const Model& model = scene_.model;
  ContactDepths d;
  int deepestBody = -1;
  for (const ManifoldSnap& m : s.manifolds)
    for (int k = m.first; k < m.first + m.count; ++k) {
      const double depth = s.contacts[static_cast<size_t>(k)].depth;
      if (!(depth > 0)) continue;
      d.sumSquares += depth * depth;
      ++d.points;
      if (depth > d.deepest) {
        d.deepest = depth;
        deepestBody = model.bodies[static_cast<size_t>(m.a)].isStatic ? m.b : m.a;
      }
    }
  const bool finite = s.state.finite();
  if (s.state.step > 0) probe_.observe(s.state, d, finite);

  auto mark = [&](std::optional<TimelineMarker>& worst, const char* kind, double value, int body, std::string text) {
    if (!(value > 0) || (worst && worst->value >= value)) return;
    worst = TimelineMarker{kind, s.state.step, s.state.time, body, value, std::move(text)};
  };
  mark(pen_, "penetration", d.deepest, deepestBody, lengthText("deepest contact", d.deepest));
  int jointBody = -1;
  double jointWorst = 0;
  for (size_t k = 0; k < s.joints.size() && k < model.joints.size(); ++k)
    if (s.joints[k].error > jointWorst) {
      jointWorst = s.joints[k].error;
      jointBody = model.joints[k].bodyB;
    }
  mark(joint_, "joint_error", jointWorst, jointBody, lengthText("largest joint error", jointWorst));
  int fastest = -1;
  double speed = 0;
  for (size_t i = 0; i < s.state.bodies.size(); ++i)
    if (!model.bodies[i].isStatic && s.state.bodies[i].v.norm() > speed) {
      speed = s.state.bodies[i].v.norm();
      fastest = static_cast<int>(i);
    }
  char buf[64];
  std::snprintf(buf, sizeof buf, "fastest body %.3g m/s", speed);
  mark(speed_, "speed", speed, fastest, buf);

  // The bounds on the metrics of the run so far: a copy of the probe finished (finish() ends a
  // probe), until every bound has failed.
  if (open_ == 0 || s.state.step == 0) return;
  Probe sofar = probe_;
  const Metrics& m = sofar.finish();
  const auto& pass = scene_.criteria->pass;
  for (size_t k = 0; k < pass.size(); ++k) {
    if (failed_[k]) continue;
    const std::optional<double> value = metricValue(m, pass[k].first);
    if (!value) continue;  // not measured (yet): no failure to mark
    const Check c = checkAtMost(pass[k].first, value, pass[k].second);
    if (c.ok) continue;
    int body = -1;
    const std::string& name = pass[k].first;
    if (name.rfind("penetration", 0) == 0) body = deepestBody;
    else if (name.rfind("joint", 0) == 0) body = jointBody;
    else if (name == "speed") body = fastest;
    else if (name == "displacement" && !m.displacementBody.empty()) body = model.bodyIndex(m.displacementBody);
    else if (name == "sideways" && !m.sidewaysBody.empty()) body = model.bodyIndex(m.sidewaysBody);
    failed_[k] = TimelineMarker{"criterion", s.state.step, s.state.time, body, *value, c.text};
    --open_;
  }
}

std::vector<TimelineMarker> TimelineWatch::markers() const {
  std::vector<TimelineMarker> out;
  for (const auto& f : failed_)
    if (f) out.push_back(*f);
  for (const auto* w : {&pen_, &joint_, &speed_})
    if (*w) out.push_back(**w);
  return out;
}

std::optional<TimelineMarker> TimelineWatch::worst(const std::string& kind) const {
  if (kind == "penetration") return pen_;
  if (kind == "joint_error") return joint_;
  if (kind == "speed") return speed_;
  return std::nullopt;
}

}  // namespace substep::lab

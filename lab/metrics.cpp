#include "lab/metrics.h"

#include "physics/constraints/joints.h"

#include <cmath>
#include <cstdio>

namespace substep::lab {

namespace {

Vec3 angularMomentum(const Body& b, const BodyState& s) { return s.q * b.inertia.cwiseProduct(s.w); }  // world, about the centre

// Total linear momentum and angular momentum about the origin of the dynamic bodies.
void momentum(const Model& model, const State& s, Vec3& p, Vec3& l) {
  p.setZero();
  l.setZero();
  for (size_t i = 0; i < model.bodies.size(); ++i) {
    const Body& b = model.bodies[i];
    if (b.isStatic) continue;
    const BodyState& x = s.bodies[i];
    p += b.mass * x.v;
    l += x.x.cross(b.mass * x.v) + angularMomentum(b, x);
  }
}

std::string fixed(double x, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, x);
  return buf;
}

}  // namespace

std::optional<double> metricValue(const Metrics& m, const std::string& name) {
  if (name == "penetration") return m.penetrationMax;
  if (name == "penetration_end") return m.penetrationEnd;
  if (name == "joint_error") return m.joints ? std::optional<double>(m.jointErrorMax) : std::nullopt;
  if (name == "joint_angle_error") return m.joints ? std::optional<double>(m.jointAngleErrorMax) : std::nullopt;
  if (name == "limit_excess") return m.joints ? std::optional<double>(m.limitExcess.max()) : std::nullopt;
  if (name == "displacement") return m.displacementMax;
  if (name == "sideways") return m.sidewaysMax;
  if (name == "jitter") return m.jitter;
  if (name == "speed") return m.speedMax;
  if (name == "energy_drift") return m.energyDrift;
  if (name == "momentum_drift") {
    if (m.linearMomentumDrift && m.angularMomentumDrift) return std::max(*m.linearMomentumDrift, *m.angularMomentumDrift);
    return m.linearMomentumDrift ? m.linearMomentumDrift : m.angularMomentumDrift;
  }
  if (name == "trajectory_error") return m.trajectoryError;
  if (name == "reference_error") return m.referenceError;
  return std::nullopt;
}

const char* metricUnit(const std::string& name) {
  if (name == "joint_angle_error" || name == "limit_excess") return "rad";
  if (name == "jitter" || name == "speed") return "m/s";
  if (name == "energy_drift" || name == "momentum_drift" || name == "reference_error") return "";
  return "m";
}

const char* metricLabel(const std::string& name) {
  if (name == "penetration") return "max penetration";
  if (name == "penetration_end") return "penetration at the end";
  if (name == "joint_error") return "max joint error";
  if (name == "joint_angle_error") return "max joint angle error";
  if (name == "limit_excess") return "max limit excess";
  if (name == "displacement") return "max displacement";
  if (name == "sideways") return "max sideways displacement";
  if (name == "jitter") return "resting jitter";
  if (name == "speed") return "max speed";
  if (name == "energy_drift") return "energy drift";
  if (name == "momentum_drift") return "momentum drift";
  if (name == "trajectory_error") return "trajectory error";
  if (name == "reference_error") return "error against the closed form";
  return "?";
}

namespace {

std::string significant(double x, const char* unit, int extraDigits) {
  char buf[64];
  const double a = std::abs(x);
  const int decimals = (a >= 100 ? 0 : a >= 10 ? 1 : a >= 1 ? 2 : 3) + extraDigits;
  std::snprintf(buf, sizeof buf, "%.*f%s%s", decimals, x, unit[0] ? " " : "", unit);
  return buf;
}

}  // namespace

std::string formatLength(double m, int extraDigits) {
  const double a = std::abs(m);
  if (a < 0.01) return significant(m * 1e3, "mm", extraDigits);
  if (a < 1) return significant(m * 1e2, "cm", extraDigits);
  if (a < 1e4) return significant(m, "m", extraDigits);
  return numberText(m) + " m";
}

std::string formatMetric(const std::string& name, double value, int extraDigits) {
  if (!std::isfinite(value)) return numberText(value);
  const std::string unit = metricUnit(name);
  if (unit == "m") return formatLength(value, extraDigits);
  if (unit == "rad") return significant(value * 180 / 3.14159265358979323846, "deg", extraDigits);
  if (unit.empty()) return significant(value * 100, "%", extraDigits);
  return significant(value, unit.c_str(), extraDigits);
}

PreparedReference prepareReference(const Scene& scene, const SceneReference& ref, double seconds) {
  PreparedReference p;
  p.kind = ref.kind;
  if (ref.kind == SceneReference::Kind::Pendulum) p.pendulum = pendulumModel(scene, ref);
  if (ref.kind == SceneReference::Kind::Converged) p.converged = convergedReference(scene, ref, seconds, kTrajectoryInterval);
  return p;
}

Probe::Probe(const Scene& scene, double seconds, const PreparedReference* reference)
    : scene_(scene), model_(scene.model), seconds_(seconds), reference_(reference), watch_(scene.model, scene.initial) {
  const std::optional<SceneCriteria>& c = scene.criteria;
  m_.joints = static_cast<int>(model_.joints.size());
  if (c && !c->rest.empty()) {
    rest_ = c->rest;
  } else {
    for (size_t i = 0; i < model_.bodies.size(); ++i)
      if (!model_.bodies[i].isStatic) rest_.push_back(static_cast<int>(i));
  }
  conservative_ = c && c->conservative;
  bool anyStatic = false;
  for (const Body& b : model_.bodies) anyStatic = anyStatic || b.isStatic;
  free_ = model_.gravity.norm() == 0 && !anyStatic;
  if (model_.gravity.norm() > 0) down_ = model_.gravity.normalized();
  m_.energyStart = m_.energyEnd = mechanicalEnergy(model_, scene.initial);
  keMax_ = kineticEnergy(model_, scene.initial);
  momentum(model_, scene.initial, p0_, l0_);
  m_.collapseRule = c && c->tolerance ? "a resting body moved more than " + numberText(*c->tolerance) + " m"
                                      : "sideways beyond half a body's size, or the top fell by its height (physics/failure.h)";
  if (reference_) {
    if (reference_->pendulum) {
      times_.push_back(0);
      angles_.push_back(reference_->pendulum->theta0);
    }
    if (reference_->converged) sampler_.emplace(model_, scene.initial, kTrajectoryInterval);
    if (reference_->kind == SceneReference::Kind::TorqueFree)
      for (size_t i = 0; i < model_.bodies.size(); ++i)
        l0Bodies_.push_back(model_.bodies[i].isStatic ? Vec3::Zero() : angularMomentum(model_.bodies[i], scene.initial.bodies[i]));
  }
  last_ = scene.initial;
}

std::string Probe::stop(const Engine&) {
  if (!diverged()) return {};
  return "the mechanical energy grew beyond 100 times the energy that lifts every body by its size";
}

void Probe::observe(const State& s, const ContactDepths& contacts, bool finite) {
  watch_.observe(s, finite);
  const bool ownTolerance = scene_.criteria && scene_.criteria->tolerance;
  if (!ownTolerance && !m_.collapseTime && watch_.report().collapseTime >= 0) m_.collapseTime = watch_.report().collapseTime;
  if (!finite) return;  // the values may be NaN; the record says where it stopped
  last_ = s;
  const double t = s.time;
  // Contacts.
  m_.penetrationMax = std::max(m_.penetrationMax, contacts.deepest);
  m_.penetrationEnd = contacts.deepest;
  penSum_ += contacts.sumSquares;
  penCount_ += contacts.points;
  // Joints.
  for (const Joint& j : model_.joints) {
    const Pose A = s.bodies[static_cast<size_t>(j.bodyA)].pose(), B = s.bodies[static_cast<size_t>(j.bodyB)].pose();
    const double e = jointError(j, A, B), a = jointAngularError(j, A, B);
    const LimitExcess l = jointLimitExcess(j, A, B);
    m_.jointErrorMax = std::max(m_.jointErrorMax, e);
    m_.jointAngleErrorMax = std::max(m_.jointAngleErrorMax, a);
    jointSum_ += e * e;
    ++jointSamples_;
    JointKindError& k = m_.byKind[jointTypeName(j.type)];
    k.max = std::max(k.max, e);
    k.angleMax = std::max(k.angleMax, a);
    k.sumSquares += e * e;
    ++k.samples;
    m_.limitExcess.hinge = std::max(m_.limitExcess.hinge, l.hinge);
    m_.limitExcess.swing = std::max(m_.limitExcess.swing, l.swing);
    m_.limitExcess.twist = std::max(m_.limitExcess.twist, l.twist);
  }
  // Energy and momentum.
  m_.energyEnd = mechanicalEnergy(model_, s);
  keMax_ = std::max(keMax_, kineticEnergy(model_, s));
  if (conservative_) m_.energyDrift = std::max(m_.energyDrift.value_or(0), std::abs(m_.energyEnd - m_.energyStart));
  if (free_) {
    Vec3 p, l;
    momentum(model_, s, p, l);
    m_.linearMomentumDrift = std::max(m_.linearMomentumDrift.value_or(0), (p - p0_).norm());
    m_.angularMomentumDrift = std::max(m_.angularMomentumDrift.value_or(0), (l - l0_).norm());
  }
  // Resting bodies and speeds.
  const double tolerance = ownTolerance ? *scene_.criteria->tolerance : INFINITY;
  for (int i : rest_) {
    const BodyState& b = s.bodies[static_cast<size_t>(i)];
    const double d = (b.x - scene_.initial.bodies[static_cast<size_t>(i)].x).norm();
    if (d > m_.displacementMax) {
      m_.displacementMax = d;
      m_.displacementBody = model_.bodies[static_cast<size_t>(i)].name;
    }
    const Vec3 moved = b.x - scene_.initial.bodies[static_cast<size_t>(i)].x;
    const double across = (moved - moved.dot(down_) * down_).norm();
    if (across > m_.sidewaysMax) {
      m_.sidewaysMax = across;
      m_.sidewaysBody = model_.bodies[static_cast<size_t>(i)].name;
    }
    if (d > tolerance && !m_.collapseTime) m_.collapseTime = t;
    if (t >= 0.5 * seconds_ - 1e-9) m_.jitter = std::max(m_.jitter, b.v.norm());
  }
  for (size_t i = 0; i < model_.bodies.size(); ++i)
    if (!model_.bodies[i].isStatic) m_.speedMax = std::max(m_.speedMax, s.bodies[i].v.norm());
  // References.
  if (reference_) {
    if (const auto& p = reference_->pendulum) {
      const Vec3 x = s.bodies[static_cast<size_t>(p->body)].x;
      times_.push_back(t);
      angles_.push_back(p->angleOf(x));
      if (p->fromRest) {
        const double e = (x - p->positionAt(t, scene_.initial.bodies[static_cast<size_t>(p->body)].x)).norm();
        pendulumMax_ = std::max(pendulumMax_, e);
        pendulumSum_ += e * e;
        ++pendulumCount_;
      }
    }
    if (reference_->kind == SceneReference::Kind::FreeFall) {
      for (size_t i = 0; i < model_.bodies.size(); ++i) {
        if (model_.bodies[i].isStatic) continue;
        const BodyState& b0 = scene_.initial.bodies[i];
        const Vec3 x = b0.x + b0.v * t + 0.5 * model_.gravity * t * t;
        const double e = (s.bodies[i].x - x).norm();
        freeFallMax_ = std::max(freeFallMax_, e);
        freeFallSum_ += e * e;
        ++freeFallCount_;
      }
    }
    if (reference_->kind == SceneReference::Kind::TorqueFree)
      for (size_t i = 0; i < model_.bodies.size(); ++i) {
        const double l0 = l0Bodies_[i].norm();
        if (model_.bodies[i].isStatic || !(l0 > 0)) continue;
        torqueFreeDrift_ = std::max(torqueFreeDrift_, (angularMomentum(model_.bodies[i], s.bodies[i]) - l0Bodies_[i]).norm() / l0);
      }
    if (sampler_) sampler_->observe(s);
  }
  // The scene's own checks.
  if (const auto& c = scene_.criteria) {
    if (c->stayIn) {
      const Vec3 x = s.bodies[static_cast<size_t>(c->stayIn->body)].x;
      const bool in = (x.array() >= c->stayIn->lo.array()).all() && (x.array() <= c->stayIn->hi.array()).all();
      m_.stayedIn = m_.stayedIn.value_or(true) && in;
    }
    if (c->turns) {
      const Vec3 a0 = scene_.initial.bodies[static_cast<size_t>(c->turns->body)].q * c->turns->axis;
      const Vec3 a = s.bodies[static_cast<size_t>(c->turns->body)].q * c->turns->axis;
      m_.turnedMost = std::max(m_.turnedMost.value_or(0), std::atan2(a0.cross(a).norm(), a0.dot(a)));
    }
  }
}

const Metrics& Probe::finish() {
  m_.penetrationRms = penCount_ ? std::sqrt(penSum_ / static_cast<double>(penCount_)) : 0;
  m_.jointErrorRms = jointSamples_ ? std::sqrt(jointSum_ / static_cast<double>(jointSamples_)) : 0;
  for (auto& [kind, k] : m_.byKind) k.rms = k.samples ? std::sqrt(k.sumSquares / static_cast<double>(k.samples)) : 0;
  // Energy drift as a share of the energy in play: the largest kinetic energy of the run.
  if (conservative_) {
    const double scale = keMax_ > 0 ? keMax_ : std::max(std::abs(m_.energyStart), 1e-300);
    m_.energyDrift = m_.energyDrift.value_or(0) / scale;
    m_.energyDriftEnd = (m_.energyEnd - m_.energyStart) / scale;
  }
  if (free_) {
    // Shares of the start's momentum; a body at rest has none to share, so its drift stays in N s.
    if (p0_.norm() > 0) m_.linearMomentumDrift = *m_.linearMomentumDrift / p0_.norm();
    if (l0_.norm() > 0) m_.angularMomentumDrift = *m_.angularMomentumDrift / l0_.norm();
  }
  m_.failure = watch_.report();
  if (reference_) {
    if (const auto& p = reference_->pendulum) {
      m_.periodReference = p->period();
      const double T = measuredPeriod(times_, angles_);
      if (std::isfinite(T)) {
        m_.periodMeasured = T;
        m_.referenceError = std::abs(T - p->period()) / p->period();
        m_.referenceText = "period " + fixed(T, 4) + " s, closed form " + fixed(p->period(), 4) + " s (amplitude " +
                           fixed(p->amplitude * 180 / 3.14159265358979323846, 1) + " degrees)";
      } else {
        m_.referenceText = "fewer than three zero crossings in the run: no period measured";
      }
      if (p->fromRest && pendulumCount_) {
        m_.trajectoryError = pendulumMax_;
        m_.trajectoryErrorRms = std::sqrt(pendulumSum_ / static_cast<double>(pendulumCount_));
      }
    }
    if (reference_->kind == SceneReference::Kind::FreeFall && freeFallCount_) {
      m_.trajectoryError = freeFallMax_;
      m_.trajectoryErrorRms = std::sqrt(freeFallSum_ / static_cast<double>(freeFallCount_));
    }
    if (reference_->kind == SceneReference::Kind::TorqueFree) {
      m_.referenceError = torqueFreeDrift_;
      m_.referenceText = "world angular momentum of each body kept to " + fixed(100 * torqueFreeDrift_, 3) + " %";
    }
    if (sampler_ && reference_->converged) {
      const TrajectoryDifference d = difference(*sampler_, reference_->converged->trajectory);
      m_.trajectoryError = d.max;
      m_.trajectoryErrorRms = d.rms;
      m_.referenceText = "against " + reference_->converged->method + " at h/2 (halving h moved it " +
                         numberText(reference_->converged->change) + " m)";
    }
  }
  if (const auto& c = scene_.criteria; c && c->moving) {
    double least = INFINITY;
    for (int i : c->moving->bodies)
      least = std::min(least, (last_.bodies[static_cast<size_t>(i)].x - scene_.initial.bodies[static_cast<size_t>(i)].x).norm());
    m_.movingLeast = least;
  }
  return m_;
}

std::string comparisonText(const std::string& metric, double value, const char* op, double bound) {
  std::string v = formatMetric(metric, value), b = formatMetric(metric, bound);
  // As many more digits as it takes for two different numbers not to print the same.
  for (int more = 1; v == b && value != bound && more <= 6; ++more)
    v = formatMetric(metric, value, more), b = formatMetric(metric, bound, more);
  return std::string(metricLabel(metric)) + " " + v + " " + op + " " + b;
}

}  // namespace substep::lab

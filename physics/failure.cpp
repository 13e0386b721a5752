#include "physics/failure.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace substep {

namespace {

// Half the smallest dimension of a shape across gravity: how far a body may move sideways
// before it no longer rests on what it rested on.
double halfSize(const Shape& s) {
  switch (s.type) {
    case ShapeType::Box: return s.halfExtents.minCoeff();
    case ShapeType::Sphere:
    case ShapeType::Capsule:
    case ShapeType::Cylinder: return s.radius;
    default: return 0.5 * s.boundingRadius();
  }
}

}  // namespace

Displacement largestDisplacement(const Model& model, const State& from, const State& now, const std::vector<int>* only) {
  Displacement d;
  auto visit = [&](size_t i) {
    const Vec3 by = now.bodies[i].x - from.bodies[i].x;
    const double m = by.norm();
    if (d.body < 0 || m > d.metres) d = Displacement{m, static_cast<int>(i), by};
  };
  if (only)
    for (int i : *only) visit(static_cast<size_t>(i));
  else
    for (size_t i = 0; i < model.bodies.size(); ++i)
      if (!model.bodies[i].isStatic) visit(i);
  return d;
}

double kineticEnergy(const Model& model, const State& s) {
  double e = 0;
  for (size_t i = 0; i < model.bodies.size(); ++i) {
    const Body& b = model.bodies[i];
    if (b.isStatic) continue;
    e += kineticEnergy(b, s.bodies[i]);
  }
  return e;
}

double kineticEnergy(const Body& b, const BodyState& x) {
  return 0.5 * b.mass * x.v.squaredNorm() + 0.5 * x.w.dot(b.inertia.cwiseProduct(x.w));
}

double potentialEnergy(const Model& model, const State& s) {
  double e = 0;
  for (size_t i = 0; i < model.bodies.size(); ++i)
    if (!model.bodies[i].isStatic) e -= model.bodies[i].mass * model.gravity.dot(s.bodies[i].x);
  return e;
}

double mechanicalEnergy(const Model& model, const State& s) { return kineticEnergy(model, s) + potentialEnergy(model, s); }

std::string FailureReport::verdict() const {
  char buf[96];
  if (divergeTime >= 0) std::snprintf(buf, sizeof buf, "diverges at %.2f s", divergeTime);
  else if (collapseTime >= 0) std::snprintf(buf, sizeof buf, "collapses at %.2f s", collapseTime);
  else std::snprintf(buf, sizeof buf, "stands (sag %.1f cm)", 100 * maxSag);
  return buf;
}

FailureWatch::FailureWatch(const Model& model, const State& initial, const FailureCriteria& criteria)
    : model_(model), criteria_(criteria) {
  const double g = model.gravity.norm();
  up_ = g > 0 ? Vec3(-model.gravity / g) : Vec3::UnitY();
  size_.assign(model.bodies.size(), 0.0);
  x0_.resize(model.bodies.size());
  double best = -INFINITY;
  for (size_t i = 0; i < model.bodies.size(); ++i) {
    const Body& b = model.bodies[i];
    x0_[i] = initial.bodies[i].x;
    if (b.isStatic) continue;
    size_[i] = halfSize(b.shape);
    energyScale_ += b.mass * g * 2 * b.shape.boundingRadius();
    const double h = up_.dot(x0_[i]);
    if (h > best) best = h, top_ = static_cast<int>(i);
  }
  if (top_ >= 0) {
    topHeight0_ = best;
    topSize_ = 2 * model.bodies[static_cast<size_t>(top_)].shape.boundingRadius();
  }
  energy0_ = mechanicalEnergy(model, initial);
  // Without gravity the lifting energy is zero, and a spinning body's round-off would count as
  // divergence: the kinetic energy at the start is in play too.
  energyScale_ = std::max(energyScale_ + kineticEnergy(model, initial), 1e-9);
}

void FailureWatch::observe(const State& s, bool finite) {
  FailureReport& r = report_;
  if (r.divergeTime >= 0) return;
  const double t = s.time;
  const double gain = finite && s.finite() ? mechanicalEnergy(model_, s) - energy0_ : INFINITY;
  r.maxEnergyGain = std::max(r.maxEnergyGain, gain);
  if (!std::isfinite(gain) || gain > criteria_.energyFactor * energyScale_) {
    r.divergeTime = t;
    return;
  }
  double top = -INFINITY;
  for (size_t i = 0; i < model_.bodies.size(); ++i) {
    if (model_.bodies[i].isStatic) continue;
    const BodyState& b = s.bodies[i];
    const Vec3 d = b.x - x0_[i];
    const double down = -up_.dot(d);
    const double sideways = (d + down * up_).norm();
    r.maxSpeed = std::max(r.maxSpeed, b.v.norm());
    r.maxSideways = std::max(r.maxSideways, sideways);
    top = std::max(top, up_.dot(b.x));
    if (r.collapseTime < 0 && sideways > size_[i]) {
      r.collapseTime = t;
      r.collapsedBody = model_.bodies[i].name;
    }
    if (r.collapseTime < 0) {
      r.maxSag = std::max(r.maxSag, down);
      if (r.sagTime < 0 && down > criteria_.sagTolerance) r.sagTime = t;
    }
  }
  if (r.collapseTime < 0 && top_ >= 0 && topHeight0_ - top > topSize_) {
    r.collapseTime = t;
    r.collapsedBody = "top";
  }
}

}  // namespace substep

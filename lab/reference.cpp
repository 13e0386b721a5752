#include "lab/reference.h"

#include "physics/run.h"

#include "lab/method.h"
#include "physics/world.h"

#include <cmath>
#include <cstdio>

namespace substep::lab {

namespace {

constexpr double kPi = 3.14159265358979323846;

std::string fixed(double x, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, x);
  return buf;
}

}  // namespace

double ellipticK(double k) {
  if (!(k >= 0 && k < 1)) throw std::invalid_argument("ellipticK: the modulus must be in [0, 1), got " + numberText(k));
  return std::comp_ellint_1(k);  // C++17's special functions: K(k), k the modulus
}

double jacobiSn(double u, double k) {
  // Abramowitz and Stegun 16.4: the AGM sequence, then back down from φ_N = 2^N a_N u.
  double a[64], c[64];
  a[0] = 1;
  double b = std::sqrt(1 - k * k);
  c[0] = k;
  int n = 0;
  while (std::abs(c[n]) > 1e-16 && n < 62) {
    a[n + 1] = 0.5 * (a[n] + b);
    c[n + 1] = 0.5 * (a[n] - b);
    b = std::sqrt(a[n] * b);
    ++n;
  }
  double phi = std::ldexp(a[n] * u, n);
  for (int j = n; j > 0; --j) phi = 0.5 * (phi + std::asin(c[j] / a[j] * std::sin(phi)));
  return std::sin(phi);
}

double PendulumModel::smallPeriod() const { return 2 * kPi / omega0; }

double PendulumModel::period() const { return 4 * ellipticK(std::sin(0.5 * amplitude)) / omega0; }

double PendulumModel::angleAt(double t) const {
  // Released at rest from the amplitude: θ = 2 asin(k sn(K - ω0 t, k)), k = sin(A/2).
  const double k = std::sin(0.5 * amplitude);
  const double s = jacobiSn(ellipticK(k) - omega0 * t, k);
  return 2 * std::asin(std::max(-1.0, std::min(1.0, k * s)));
}

double PendulumModel::angleOf(const Vec3& x) const {
  const Vec3 d = x - pivot;
  return std::atan2(axis.dot(down.cross(d)), down.dot(d));
}

Vec3 PendulumModel::positionAt(double t, const Vec3& x0) const {
  return pivot + Eigen::AngleAxisd(angleAt(t) - theta0, axis) * (x0 - pivot);
}

PendulumModel pendulumModel(const Scene& scene, const SceneReference& ref) {
  PendulumModel p;
  p.body = scene.model.bodyIndex(ref.body);
  if (p.body < 0) throw std::invalid_argument("pendulum reference: unknown body \"" + ref.body + "\"");
  const Body& b = scene.model.bodies[static_cast<size_t>(p.body)];
  const BodyState& s = scene.initial.bodies[static_cast<size_t>(p.body)];
  const double g = scene.model.gravity.norm();
  if (!(g > 0)) throw std::invalid_argument("pendulum reference: the scene has no gravity");
  p.pivot = ref.pivot;
  p.down = scene.model.gravity / g;
  const Vec3 d0 = s.x - p.pivot;
  p.distance = d0.norm();
  Vec3 n = p.down.cross(d0);
  if (n.norm() < 1e-9 * p.distance) n = d0.cross(s.v);
  if (n.norm() < 1e-12) throw std::invalid_argument("pendulum reference: \"" + ref.body + "\" hangs at rest: it does not swing");
  p.axis = n.normalized();
  if (std::abs(s.v.dot(p.axis)) > 1e-9 + 1e-6 * s.v.norm())
    throw std::invalid_argument("pendulum reference: \"" + ref.body + "\" moves out of its swing plane at the start");
  const Vec3 nb = s.q.conjugate() * p.axis;  // the axis in the body frame, where the inertia is diagonal
  p.inertia = nb.dot(b.inertia.cwiseProduct(nb)) + b.mass * p.distance * p.distance;
  p.omega0 = std::sqrt(b.mass * g * p.distance / p.inertia);
  p.theta0 = p.angleOf(s.x);
  const double rate = p.axis.dot(d0.cross(s.v)) / (p.distance * p.distance);
  p.fromRest = std::abs(rate) < 1e-12;
  const double lift = (1 - std::cos(p.theta0)) + p.inertia * rate * rate / (2 * b.mass * g * p.distance);
  if (lift >= 2) throw std::invalid_argument("pendulum reference: \"" + ref.body + "\" goes over the top: it turns, not swings");
  p.amplitude = std::acos(1 - lift);
  return p;
}

double measuredPeriod(const std::vector<double>& times, const std::vector<double>& angles) {
  std::vector<double> crossings;
  for (size_t i = 1; i < times.size() && i < angles.size(); ++i) {
    const double a = angles[i - 1], b = angles[i];
    if ((a < 0 && b >= 0) || (a > 0 && b <= 0)) crossings.push_back(times[i - 1] + (times[i] - times[i - 1]) * a / (a - b));
  }
  if (crossings.size() < 3) return NAN;
  return 2 * (crossings.back() - crossings.front()) / static_cast<double>(crossings.size() - 1);
}

TrajectorySampler::TrajectorySampler(const Model& model, const State& initial, double interval) : interval_(interval) {
  for (size_t i = 0; i < model.bodies.size(); ++i)
    if (!model.bodies[i].isStatic) bodies_.push_back(static_cast<int>(i));
  for (int i : bodies_) last_.push_back(initial.bodies[static_cast<size_t>(i)].x);
  lastTime_ = initial.time;
  samples_.push_back(last_);
}

void TrajectorySampler::observe(const State& s) {
  for (;;) {
    const double t = static_cast<double>(samples_.size()) * interval_;
    if (t > s.time + 1e-9 * interval_) break;
    const double span = s.time - lastTime_;
    const double f = span > 0 ? std::min(1.0, (t - lastTime_) / span) : 1.0;
    std::vector<Vec3> row(bodies_.size());
    for (size_t k = 0; k < bodies_.size(); ++k)
      row[k] = last_[k] + f * (s.bodies[static_cast<size_t>(bodies_[k])].x - last_[k]);
    samples_.push_back(std::move(row));
  }
  for (size_t k = 0; k < bodies_.size(); ++k) last_[k] = s.bodies[static_cast<size_t>(bodies_[k])].x;
  lastTime_ = s.time;
}

TrajectoryDifference difference(const TrajectorySampler& a, const TrajectorySampler& b) {
  TrajectoryDifference d;
  double sum = 0;
  const size_t n = std::min(a.samples().size(), b.samples().size());
  for (size_t k = 0; k < n; ++k) {
    const auto &ra = a.samples()[k], &rb = b.samples()[k];
    for (size_t i = 0; i < ra.size() && i < rb.size(); ++i) {
      const double e = (ra[i] - rb[i]).norm();
      d.max = std::max(d.max, e);
      sum += e * e;
      ++d.samples;
    }
  }
  d.rms = d.samples ? std::sqrt(sum / static_cast<double>(d.samples)) : 0;
  return d;
}

namespace {

// The scene under `settings` for `seconds`, sampled; throws ReferenceError when it stops.
class Sample final : public RunObserver {
 public:
  explicit Sample(TrajectorySampler& s) : s_(s) {}
  void observe(const Engine& e, const StepRecord& r) override {
    if (r.finite) s_.observe(e.state());
  }

 private:
  TrajectorySampler& s_;
};

// Ends a run once the wall clock passes a deadline.
class Deadline final : public RunObserver {
 public:
  explicit Deadline(std::chrono::steady_clock::time_point at) : at_(at) {}
  std::string stop(const Engine&) override { return std::chrono::steady_clock::now() >= at_ ? "out of time" : ""; }

 private:
  std::chrono::steady_clock::time_point at_;
};

TrajectorySampler sampledRun(const Scene& scene, const SolverSettings& settings, double seconds, double interval,
                             const std::string& what, std::chrono::steady_clock::time_point deadline) {
  TrajectorySampler sampler(scene.model, scene.initial, interval);
  World world(scene.model, settings, scene.initial);
  WorldEngine engine(world);
  Sample sample(sampler);
  Deadline stop(deadline);
  RunDriver run(engine, static_cast<long long>(std::ceil(seconds / settings.dt - 1e-9)));
  const RunOutcome& o = run.add(sample).add(stop).run();
  if (o.end == RunOutcome::End::Refused) throw ReferenceError(what + " cannot run the scene: " + o.message);
  if (o.end == RunOutcome::End::Diverged) throw ReferenceError(what + ": " + o.message);
  if (o.end == RunOutcome::End::Stopped)
    throw TimeBudgetSpent(what + " was at step " + std::to_string(o.steps) + " of " + std::to_string(run.planned()));
  return sampler;
}

}  // namespace

ConvergedReference convergedReference(const Scene& scene, const SceneReference& ref, double seconds, double interval,
                                      std::chrono::steady_clock::time_point deadline) {
  const std::vector<Method> m = parseMethods(ref.method);
  if (m.size() != 1 || m[0].isPeer())
    throw ReferenceError("reference \"" + ref.method + "\": expected one of substep's algorithms at a small h");
  const SolverSettings coarse = methodSettings(m[0], scene, m[0].overrides.get(&SolverSettings::dt));
  SolverSettings fine = coarse;
  fine.dt = coarse.dt / 2;
  const std::string what = "the reference " + ref.method;
  TrajectorySampler a = sampledRun(scene, coarse, seconds, interval, what, deadline);
  TrajectorySampler b = sampledRun(scene, fine, seconds, interval, what + " at h/2", deadline);
  double motion = 0;
  for (const auto& row : b.samples())
    for (size_t i = 0; i < row.size(); ++i) motion = std::max(motion, (row[i] - b.samples()[0][i]).norm());
  const double change = difference(a, b).max;
  if (change > ref.change * motion)
    throw ReferenceError(what + " is not converged: halving h to " + stepText(fine.dt) + " moved the trajectory by " +
                         numberText(change) + " m, " + fixed(100 * change / std::max(motion, 1e-300), 2) +
                         " % of the motion (" + numberText(motion) + " m) in " + numberText(seconds) +
                         " s; the scene allows " + fixed(100 * ref.change, 2) +
                         " %. Use a smaller h, a shorter run, or a method that converges here (a1 or a3)");
  return ConvergedReference{ref.method, fine.dt, std::move(b), change, motion};
}

}  // namespace substep::lab

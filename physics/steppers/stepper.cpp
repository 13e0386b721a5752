#include "physics/steppers/stepper.h"

#include <algorithm>
#include <cmath>

namespace substep {

void addExternal(StepContext& c, double dt) {
  const Vec3 dv = dt * c.model->gravity;
  for (size_t i = 0; i < c.bodies(); ++i)
    if (c.mass[i].invMass > 0) c.v[i] += dv;
}

void applyRowImpulses(ConstraintSet& cs, std::vector<Vec3>& v, std::vector<Vec3>& w) {
  for (const Row& r : cs.rows)
    if (r.lambda != 0) applyImpulse(r, r.lambda, v.data(), w.data());
}

double sweep(ConstraintSet& cs, std::vector<Vec3>& vv, std::vector<Vec3>& ww, double cBias, double cVel,
             double cBiasTarget, double cVelTarget) {
  Row* rows = cs.rows.data();
  Vec3* v = vv.data();
  Vec3* w = ww.data();
  double change = 0;
  for (const SolveUnit& u : cs.units) {
    if (u.size == 1) {
      Row& r = rows[u.first];
      const double cb = r.velocityTarget ? cBiasTarget : cBias;
      const double cv = r.velocityTarget ? cVelTarget : cVel;
      double dl = r.effMass * (cb * r.bias - cv * rowVelocity(r, v, w));
      double lo = r.lo, hi = r.hi;
      if (r.normalRow >= 0) {
        const double ln = rows[r.normalRow].lambda;
        lo *= ln;
        hi *= ln;
      }
      const double next = std::clamp(r.lambda + dl, lo, hi);
      dl = next - r.lambda;
      r.lambda = next;
      if (dl != 0) {
        applyImpulse(r, dl, v, w);
        if (r.effMass > 0) change = std::max(change, std::abs(dl) / r.effMass);
      }
    } else {
      // A 'stable' block: all of its rows at once, Δλ = K⁻¹ (cBias β - cVel J̌ v̌).
      Vec3 rhs = Vec3::Zero();
      for (int i = 0; i < u.size; ++i) {
        const Row& r = rows[u.first + i];
        const double cb = r.velocityTarget ? cBiasTarget : cBias;
        const double cv = r.velocityTarget ? cVelTarget : cVel;
        rhs[i] = cb * r.bias - cv * rowVelocity(r, v, w);
      }
      const Vec3 dl = u.invK * rhs;
      for (int i = 0; i < u.size; ++i) {
        Row& r = rows[u.first + i];
        r.lambda += dl[i];
        applyImpulse(r, dl[i], v, w);
        if (r.effMass > 0) change = std::max(change, std::abs(dl[i]) / r.effMass);
      }
    }
  }
  return change;
}

void recordSubStep(StepContext& c, int j) {
  const size_t nb = c.bodies();
  std::copy(c.v.begin(), c.v.end(), c.subV.begin() + static_cast<long>(static_cast<size_t>(j) * nb));
  std::copy(c.w.begin(), c.w.end(), c.subW.begin() + static_cast<long>(static_cast<size_t>(j) * nb));
}

Quat stepRotation(const Quat& q, const Vec3* w, size_t stride, int n, double dt, RotationRule rule) {
  if (rule == RotationRule::Product) {
    Quat r = q;
    for (int k = 0; k < n; ++k) r = r * Rq(dt * w[static_cast<size_t>(k) * stride]);
    return r.normalized();
  }
  Vec3 sum = Vec3::Zero();
  for (int k = 0; k < n; ++k) sum += dt * w[static_cast<size_t>(k) * stride];
  return (q * Rq(sum)).normalized();
}

void stepCoordinatesEssential(StepContext& c) {
  const double h = c.h();
  for (size_t i = 0; i < c.bodies(); ++i) {
    if (c.model->bodies[i].isStatic) continue;
    BodyState& b = c.state->bodies[i];
    b.v = c.v[i];
    b.w = c.w[i];
    b.x += h * b.v;
    const Vec3 omegaWorld = b.q * b.w;
    b.q = (Rq(h * omegaWorld) * b.q).normalized();
  }
}

void stepCoordinatesSubStepped(StepContext& c, RotationRule rule) {
  const int n = c.n();
  const double dt = c.h() / n;
  const size_t nb = c.bodies();
  for (size_t i = 0; i < nb; ++i) {
    if (c.model->bodies[i].isStatic) continue;
    BodyState& b = c.state->bodies[i];
    Vec3 sum = Vec3::Zero();
    for (int k = 0; k < n; ++k) sum += dt * c.subV[static_cast<size_t>(k) * nb + i];
    b.x += sum;
    b.q = stepRotation(b.q, &c.subW[i], nb, n, dt, rule);
    b.v = c.subV[static_cast<size_t>(n - 1) * nb + i];
    b.w = c.subW[static_cast<size_t>(n - 1) * nb + i];
  }
}

}  // namespace substep

#include "physics/collision/manifold.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace substep {

void ManifoldCache::beginStep(bool keepStorage) {
  std::swap(current_, previous_);
  if (!keepStorage) current_.clear();
  cursor_ = 0;
}

void ManifoldCache::clear() {
  current_.clear();
  previous_.clear();
  cursor_ = 0;
}

namespace {

Vec3 relativePosition(const Pose& A, const Pose& B) { return A.unrotate(B.p - A.p); }
Quat relativeOrientation(const Pose& A, const Pose& B) { return A.q.conjugate() * B.q; }

}  // namespace

double pairShift(const Manifold& m, const Pose& poseA, const Pose& poseB) {
  // A point x fixed on B sits at relQ x + relP in A's frame; since detection it has moved by at
  // most |ΔrelP| + θ |x|, θ the angle of the relative turn.
  const Quat turn = m.relQ.conjugate() * relativeOrientation(poseA, poseB);
  const double theta = 2 * std::atan2(turn.vec().norm(), std::abs(turn.w()));
  return (relativePosition(poseA, poseB) - m.relP).norm() + theta * m.reach;
}

bool pairShiftBelow(const Manifold& m, const Pose& poseA, const Pose& poseB, double limit) {
  // θ/2 = atan(s/c) <= s/c (s = |turn.vec()|, c = |turn.w()|): if the shift with 2s/c for θ is
  // below the limit, so is pairShift's, and the arctangent (costly, asked for every cached pair
  // of every step) is not needed.
  const Quat turn = m.relQ.conjugate() * relativeOrientation(poseA, poseB);
  const double lin = (relativePosition(poseA, poseB) - m.relP).norm();
  const double s = turn.vec().norm(), c = std::abs(turn.w());
  if (c > 0 && lin * c + 2 * s * m.reach < limit * c) return true;
  return pairShift(m, poseA, poseB) < limit;
}

namespace {

// Pairs arrive ordered by their unordered key (min, max); last step's list is in the same order.
std::pair<int, int> pairKey(int a, int b) { return {std::min(a, b), std::max(a, b)}; }
std::pair<int, int> pairKey(const Manifold& m) { return pairKey(m.a, m.b); }

}  // namespace

const Manifold* ManifoldCache::previous(int a, int b, size_t& cursor) const {
  const auto k = pairKey(a, b);
  while (cursor < previous_.size() && pairKey(previous_[cursor]) < k) ++cursor;
  if (cursor < previous_.size() && previous_[cursor].a == a && previous_[cursor].b == b) return &previous_[cursor];
  return nullptr;
}

size_t ManifoldCache::start(int a, int b) const {
  const auto k = pairKey(a, b);
  return static_cast<size_t>(
      std::partition_point(previous_.begin(), previous_.end(), [&](const Manifold& m) { return pairKey(m) < k; }) -
      previous_.begin());
}

void ManifoldCache::reuse(const Manifold& old) {
  Manifold m;
  kept(m, old);
  take(m);
}

void ManifoldCache::kept(Manifold& m, const Manifold& old) {
  m = old;  // detection pose kept: the shift is measured from there, so it cannot creep
  aged(m);
}

void ManifoldCache::take(Manifold& m) {
  nextId_ = numberNewPoints(m, nextId_);
  current_.push_back(m);
}

void ManifoldCache::add(int a, int b, const Pose& poseA, const Pose& poseB, double friction, double restitution,
                        const ContactPatch& patch, double reach) {
  Manifold m;
  made(m, a, b, poseA, poseB, friction, restitution, patch, reach, previous(a, b));
  take(m);
}

void ManifoldCache::made(Manifold& m, int a, int b, const Pose& poseA, const Pose& poseB, double friction,
                         double restitution, const ContactPatch& patch, double reach, const Manifold* old) {
  m.a = a;
  m.b = b;
  m.friction = friction;
  m.restitution = restitution;
  m.relP = relativePosition(poseA, poseB);
  m.relQ = relativeOrientation(poseA, poseB);
  m.reach = reach;
  bool taken[kMaxManifoldPoints] = {false, false, false, false};
  for (int i = 0; i < patch.count && m.count < kMaxManifoldPoints; ++i) {
    const ContactPoint& c = patch.p[i];
    ManifoldPoint& p = m.points[m.count++];
    p.localA = poseA.unrotate(c.pA - poseA.p);
    p.localB = poseB.unrotate(c.pB - poseB.p);
    p.localN = poseB.unrotate(c.n);
    p.worldN = c.n;
    const Vec3 mid = 0.5 * (c.pA + c.pB);
    p.armA = mid - poseA.p;
    p.armB = mid - poseB.p;
    p.depth = c.depth;
    int match = -1;
    double best = kMatchDistance * kMatchDistance;
    for (int k = 0; old && k < old->count; ++k) {
      if (taken[k]) continue;
      // The same point on both bodies: on A alone, a box sliding far would keep its corners.
      const double d = std::max((old->points[k].localA - p.localA).squaredNorm(),
                                (old->points[k].localB - p.localB).squaredNorm());
      if (d < best) best = d, match = k;
    }
    if (match >= 0) {
      taken[match] = true;
      const ManifoldPoint& o = old->points[match];
      p.id = o.id;
      p.age = o.age + 1;
      p.lambda = o.lambda;
    } else {
      p.id = 0;  // take() numbers it
    }
  }
  // The pair's friction carries over while any of its points does.
  if (old)
    for (int k = 0; k < kMaxManifoldPoints; ++k)
      if (taken[k]) {
        m.frictionImpulse = old->frictionImpulse;
        m.twistImpulse = old->twistImpulse;
        if (m.count == old->count) m.blockMask = old->blockMask;
        break;
      }
}

}  // namespace substep

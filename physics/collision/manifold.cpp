#include "physics/collision/manifold.h"

#include <algorithm>
#include <utility>

namespace substep {

void ManifoldCache::beginStep() {
  std::swap(current_, previous_);
  current_.clear();
  cursor_ = 0;
}

void ManifoldCache::clear() {
  current_.clear();
  previous_.clear();
  cursor_ = 0;
}

void ManifoldCache::add(int a, int b, const Pose& poseA, const Pose& poseB, double friction, double restitution,
                        const ContactPatch& patch) {
  // Pairs arrive ordered by their unordered key (min, max); last step's list is in the same order.
  const auto key = [](const Manifold& m) { return std::make_pair(std::min(m.a, m.b), std::max(m.a, m.b)); };
  const auto k = std::make_pair(std::min(a, b), std::max(a, b));
  while (cursor_ < previous_.size() && key(previous_[cursor_]) < k) ++cursor_;
  const Manifold* old = nullptr;
  if (cursor_ < previous_.size() && previous_[cursor_].a == a && previous_[cursor_].b == b) old = &previous_[cursor_];

  Manifold m;
  m.a = a;
  m.b = b;
  m.friction = friction;
  m.restitution = restitution;
  bool taken[kMaxManifoldPoints] = {false, false, false, false};
  for (int i = 0; i < patch.count && m.count < kMaxManifoldPoints; ++i) {
    const ContactPoint& c = patch.p[i];
    ManifoldPoint& p = m.points[m.count++];
    p.localA = poseA.unrotate(c.pA - poseA.p);
    p.localB = poseB.unrotate(c.pB - poseB.p);
    p.localN = poseB.unrotate(c.n);
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
      p.id = nextId_++;
    }
  }
  // The pair's friction carries over while any of its points does.
  if (old)
    for (int k = 0; k < kMaxManifoldPoints; ++k)
      if (taken[k]) {
        std::copy(old->frictionLambda, old->frictionLambda + 3, m.frictionLambda);
        break;
      }
  current_.push_back(m);
}

}  // namespace substep

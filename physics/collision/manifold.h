// s1, manifolds: up to four contact points per touching pair, kept from step to step. A point is
// stored by its anchors in the two body frames, so it moves with the bodies; a new point whose
// anchors on both bodies lie within kMatchDistance of an old one's takes over its identity and
// impulses (for warm starting and for telling a resting contact from a new one).
#pragma once

#include "physics/collision/narrowphase.h"
#include "physics/math.h"
#include "physics/step_arrays.h"

#include <cstdint>
#include <vector>

namespace substep {

constexpr int kMaxManifoldPoints = 4;
constexpr double kMatchDistance = 0.02;  // [m]
// A pair whose relative pose has moved less than this since its manifold was detected keeps the
// manifold (points fixed on the bodies) instead of running the narrowphase
// again, as Jolt's body-pair cache does: no point of either body has moved by more [m].
constexpr double kPairCacheShift = 1e-3;

struct ManifoldPoint {
  Vec3 localA = Vec3::Zero();  // σ̌a: the point on A, in A's frame [m]
  Vec3 localB = Vec3::Zero();  // σ̌b: the point on B, in B's frame [m]
  Vec3 localN = Vec3::UnitY(); // the normal (from B to A) in B's frame
  // Where the narrowphase found the point, in the world, kept while the manifold is reused: the
  // normal, and the arms from each body's origin to the midpoint of the two surface points [m]
  // (ContactFrame::World formulates from these).
  Vec3 worldN = Vec3::UnitY();
  Vec3 armA = Vec3::Zero(), armB = Vec3::Zero();
  double depth = 0;            // penetration when detected [m] (a kept manifold does not re-measure it:
                               // the rows and snapshots measure their own at the step's poses)
  double lambda = 0;           // its normal impulse of the last step [N s]
  int age = 0;                 // steps this point has persisted
  uint32_t id = 0;             // stable identity while it persists
};

struct Manifold {
  int a = -1, b = -1;          // bodies; the normal points from b to a
  double friction = 0;         // μ of the pair
  double restitution = 0;      // e of the pair
  int count = 0;
  ManifoldPoint points[kMaxManifoldPoints];
  // The pair's friction impulses of the last step: the tangential one as a vector in B's frame,
  // so that the next step's tangents (whichever basis of the new normal) take it over by
  // projection; the twist about the normal [N s, N m s].
  Vec3 frictionImpulse = Vec3::Zero();
  double twistImpulse = 0;
  int blockMask = -1;          // contact blocks: the active set that fitted last (BlockData::lastMask)
  Vec3 relP = Vec3::Zero();    // B's origin in A's frame when the narrowphase made these points
  Quat relQ = Quat::Identity();  // B's orientation relative to A then
  double reach = 0;            // the larger distance of a point of either body from its origin that
                               // the points can lie at (bounds how far a relative turn moves one) [m]
};

// How far any point of the pair (within `reach` of its body's origin) has moved relative to the
// other body since `m` was detected: an upper bound [m].
double pairShift(const Manifold& m, const Pose& poseA, const Pose& poseB);
// pairShift(m, poseA, poseB) < limit, mostly without its arctangent.
bool pairShiftBelow(const Manifold& m, const Pose& poseA, const Pose& poseB, double limit);

// Builds this step's manifolds from narrowphase patches, matching them with last step's.
// A manifold's new points (id 0, as made() leaves them): how many; and numbered `next`, next + 1,
// ... in point order, returning the id after the last.
inline int newPoints(const Manifold& m) {
  int k = 0;
  for (int i = 0; i < m.count; ++i) k += m.points[i].id == 0;
  return k;
}
inline uint32_t numberNewPoints(Manifold& m, uint32_t next) {
  for (int i = 0; i < m.count; ++i)
    if (m.points[i].id == 0) m.points[i].id = next++;
  return next;
}

class ManifoldCache {
 public:
  // Last step's manifolds become the ones to match against; this step's list starts empty, or
  // (keepStorage, for place()) holds stale ones until placed.
  void beginStep(bool keepStorage = false);
  // Adds the manifold of pair (a, b) from `patch` (world points). Pairs must come in increasing
  // order of (min(a,b), max(a,b)) each step, so finding last step's manifold is a merge.
  void add(int a, int b, const Pose& poseA, const Pose& poseB, double friction, double restitution,
           const ContactPatch& patch, double reach);
  // Last step's manifold of pair (a, b) (same order rule as add), or null.
  const Manifold* previous(int a, int b) { return previous(a, b, cursor_); }
  // The same for one run of the step's pairs, so that threads can each merge their own: the
  // merge goes on from `cursor` (an index in last step's list), which starts at start(a, b) of
  // the run's first pair.
  const Manifold* previous(int a, int b, size_t& cursor) const;
  size_t start(int a, int b) const;  // the first of last step's manifolds whose pair is not before (a, b)
  // Keeps last step's manifold `old` for this step: same points on the bodies, ages advanced,
  // impulses kept. Call in the pair order of add().
  void reuse(const Manifold& old);

  // add() and reuse() in two halves, so that the first can run on many threads: made() and kept()
  // build a pair's manifold from last step's `old` (null: none) without touching the cache (a new
  // point gets id 0); take() then gives new points their ids and appends it, in pair order.
  // In place (a manifold is 816 bytes, a copy a measurable part of s1): made() fills a
  // default-constructed `m`; kept() overwrites any.
  static void made(Manifold& m, int a, int b, const Pose& poseA, const Pose& poseB, double friction, double restitution,
                   const ContactPatch& patch, double reach, const Manifold* old);
  static void kept(Manifold& m, const Manifold& old);
  void take(Manifold& m);
  // Or, for many threads: beginStep(true) keeps the storage of the list two steps old, place(n)
  // makes this step's list n long for the caller to fill in pair order (every element written;
  // new storage first touched on the pool's threads),
  // and claimIds(k) numbers k new points: the first of them, as k take()s would have.
  std::vector<Manifold>& place(size_t n, WorkerPool& pool = WorkerPool::callerOnly()) {
    resizeRewritten(current_, n, pool);
    return current_;
  }
  // Or, when the list is as long as last step's and each manifold kept stands where it stood (a
  // settled scene, or one where a few pairs were made again): last step's list is this step's.
  // The caller ages each it keeps (kept() is a copy and aged()) and writes those it made over
  // whichever stood in their place.
  std::vector<Manifold>& keepInPlace() {
    std::swap(current_, previous_);
    return current_;
  }
  static void aged(Manifold& m) {
    for (int i = 0; i < m.count; ++i) ++m.points[i].age;
  }
  uint32_t claimIds(uint32_t k) {
    const uint32_t first = nextId_;
    nextId_ += k;
    return first;
  }
  const std::vector<Manifold>& manifolds() const { return current_; }
  // Last step's, which previous() finds in (the cursor it leaves is the index).
  const std::vector<Manifold>& lastStep() const { return previous_; }
  std::vector<Manifold>& manifolds() { return current_; }
  void clear();

 private:
  std::vector<Manifold> current_, previous_;
  size_t cursor_ = 0;     // merge position in previous_
  uint32_t nextId_ = 1;
};

}  // namespace substep

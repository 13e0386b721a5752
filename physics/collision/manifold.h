// s1, manifolds: up to four contact points per touching pair, kept from step to step. A point is
// stored by its anchors in the two body frames, so it moves with the bodies; a new point whose
// anchors on both bodies lie within kMatchDistance of an old one's takes over its identity and
// impulses (for warm starting and for telling a resting contact from a new one).
#pragma once

#include "physics/collision/narrowphase.h"
#include "physics/math.h"

#include <cstdint>
#include <vector>

namespace substep {

constexpr int kMaxManifoldPoints = 4;
constexpr double kMatchDistance = 0.02;  // [m]

struct ManifoldPoint {
  Vec3 localA = Vec3::Zero();  // σ̌a: the point on A, in A's frame [m]
  Vec3 localB = Vec3::Zero();  // σ̌b: the point on B, in B's frame [m]
  Vec3 localN = Vec3::UnitY(); // the normal (from B to A) in B's frame
  double depth = 0;            // penetration when detected [m]
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
  double frictionLambda[3] = {0, 0, 0};  // the pair's friction impulses of the last step (t1, t2, twist)
};

// Builds this step's manifolds from narrowphase patches, matching them with last step's.
class ManifoldCache {
 public:
  void beginStep();  // last step's manifolds become the ones to match against
  // Adds the manifold of pair (a, b) from `patch` (world points). Pairs must come in increasing
  // order of (min(a,b), max(a,b)) each step, so finding last step's manifold is a merge.
  void add(int a, int b, const Pose& poseA, const Pose& poseB, double friction, double restitution,
           const ContactPatch& patch);
  const std::vector<Manifold>& manifolds() const { return current_; }
  std::vector<Manifold>& manifolds() { return current_; }
  void clear();

 private:
  std::vector<Manifold> current_, previous_;
  size_t cursor_ = 0;     // merge position in previous_
  uint32_t nextId_ = 1;
};

}  // namespace substep

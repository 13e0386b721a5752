// s1, broadphase: which pairs of bodies are close enough for the narrowphase this step.
//
// Each body's reach box is its tight box grown by `reach` on every side (half the contact margin
// and what its turning can move a point) and swept along the path free flight takes it in the
// step: the box of {0, h v, h v + h² g} (a resting box's neighbour 1 cm away is not in reach;
// grown by h²|g| sideways too, every pyramid box met both neighbours; grown by h|v| sideways, a
// falling pile's columns met their neighbours, seven pairs a box). FCL's dynamic
// AABB tree holds *fat* boxes, reach boxes grown by a margin, as Box2D and Bullet keep them: a
// body is moved in the tree only when its reach box leaves its fat box, and only then is the
// tree queried for its new neighbours. The pairs whose fat boxes overlap persist from step to
// step; each step's pairs are those of them whose reach boxes overlap. A resting pile changes
// nothing in the tree and costs one box test per candidate pair.
//
// After an update FCL rebalances the tree a few nodes at a time, and rebuilds it top down once it
// is rebuildExcess levels deeper than a balanced tree: 2 log2(n) + 10, not FCL's 10. On the settling
// 100-level pyramid a hundred bodies leave their fat boxes every other step, and FCL's own bound
// rebuilt the 5050 leaves nearly every time, 1.4 ms on the calling thread; the deeper tree it keeps
// now (about 35 levels against 13) answers the moved bodies' queries as fast (docs/benchmarks.md,
// "The broadphase tree's rebuilds"). The bound still holds a tree that keeps degrading: a row of
// boxes taken from its front to its back, one an update, grows over 260 levels deep without it.
//
// Static-static pairs, pairs a joint keeps apart and pairs the collision filter (model.h,
// mayTouch) excludes are never pairs. Planes have unbounded boxes, on which FCL's tree build
// crashes: they stay out of the tree and meet every body whose reach box reaches below them.
#pragma once

#include "physics/collision/shape_geometry.h"
#include "physics/model.h"
#include "physics/parallel.h"
#include "physics/state.h"

#include <fcl/broadphase/broadphase_dynamic_AABB_tree.h>
#include <fcl/narrowphase/collision_object.h>

#include <memory>
#include <utility>
#include <vector>

namespace substep {

class Broadphase {
 public:
  explicit Broadphase(const Model& model);
  ~Broadphase();
  // Moves every dynamic body's box to its state, grown by reach[i] on every side and swept by
  // the box of {0, move[i], move[i] + fall} (move: h v, fall: the step's h² g), and refits the tree
  // where a box left its fat box. Static bodies are not swept. The bodies' boxes are found on
  // `pool` in blocks (each writes only its bodies'); the tree is refitted on the calling thread.
  void update(const State& state, const std::vector<double>& reach, const std::vector<Vec3>& move, const Vec3& fall,
              WorkerPool& pool = WorkerPool::callerOnly());
  // Pairs (i < j by body index) whose reach boxes overlap, in increasing order: the order is the
  // solve order downstream, so it does not depend on the tree. Returns false, with the pairs found
  // so far, when there are more than maxPairs (bodies started inside each other).
  // The moved bodies' queries of the tree (read only) are shared out on `pool` in blocks; the
  // pairs are the same on any number of threads.
  bool findPairs(std::vector<std::pair<int, int>>& pairs, size_t maxPairs, WorkerPool& pool = WorkerPool::callerOnly());
  const CollisionShape& shape(int body) const { return shapes_[static_cast<size_t>(body)]; }

  // For tests and metrics: bodies moved in the tree by the last update, candidate pairs kept, the
  // tree's height (a leaf alone: 0).
  int movedLastUpdate() const { return moved_; }
  size_t candidatePairs() const { return candidates_.size(); }
  int treeHeight() const;
  // How many levels deeper than log2(leaves) the tree may grow before an update rebuilds it.
  static int rebuildExcess(int leaves);

 private:
  struct Box {
    Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
    bool overlaps(const Box& o) const { return (lo.array() <= o.hi.array()).all() && (o.lo.array() <= hi.array()).all(); }
    bool contains(const Box& o) const { return (lo.array() <= o.lo.array()).all() && (o.hi.array() <= hi.array()).all(); }
  };
  bool admitted(int i, int j) const;

  const Model& model_;
  std::vector<CollisionShape> shapes_;
  std::vector<std::unique_ptr<fcl::CollisionObjectd>> objects_;  // null for planes; their AABB is the fat box
  std::vector<Box> reachBox_;            // this step's, per body
  std::vector<Box> fat_;                 // per body: the box the tree holds
  std::vector<int> movedList_;           // bodies whose fat box changed in the last update
  std::vector<char> movedNow_;           // update(): per body, whether its fat box changed
  int moved_ = 0;
  bool registered_ = false;
  struct Plane {
    int body;
    Vec3 n;          // world normal, out of the solid
    double offset;   // n . x = offset on the surface [m]
  };
  std::vector<Plane> planes_;
  fcl::DynamicAABBTreeCollisionManagerd manager_;
  std::vector<std::pair<int, int>> excluded_;    // sorted joint pairs that do not collide
  std::vector<std::pair<int, int>> candidates_;  // sorted pairs whose fat boxes overlap
  // Scratch, kept so that a settled step allocates nothing: new candidates of moved bodies (per
  // block of them, then all), then per block the candidates and plane pairs kept; the merged
  // list, the planes' pairs, the moved bodies' tree objects.
  std::vector<std::vector<std::pair<int, int>>> blockFound_;
  std::vector<std::pair<int, int>> found_, merged_, mergeBuffer_, planePairs_;
  std::vector<size_t> runs_, nextRuns_;
  std::vector<fcl::CollisionObjectd*> movedObjects_;
};

}  // namespace substep

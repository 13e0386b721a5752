// s1, broadphase: FCL's dynamic AABB tree over all bodies but planes, each box grown by how far
// its body can move in a step; returns the pairs whose boxes overlap, minus static-static pairs
// and pairs joined by a joint that does not let them collide. Planes have unbounded boxes, on
// which FCL's tree build crashes: they stay out of the tree and meet every body whose box
// reaches below them.
#pragma once

#include "physics/collision/shape_geometry.h"
#include "physics/model.h"
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
  // Moves every dynamic body's FCL object to its state, grows its box by reach[i] on every side
  // (how far the body can get in a step, plus the contact margin) and refits the tree.
  void update(const State& state, const std::vector<double>& reach);
  // Overlapping pairs (i < j by body index), in increasing order. The order is the solve order
  // downstream, so it is made independent of the tree's traversal. Returns false, with the pairs
  // found so far, when there are more than maxPairs (bodies started inside each other).
  bool findPairs(std::vector<std::pair<int, int>>& pairs, size_t maxPairs);
  const CollisionShape& shape(int body) const { return shapes_[static_cast<size_t>(body)]; }

 private:
  const Model& model_;
  std::vector<CollisionShape> shapes_;
  struct Object;  // an FCL object whose box can be grown
  std::vector<std::unique_ptr<Object>> objects_;  // null for planes
  struct Plane {
    int body;
    Vec3 n;          // world normal, out of the solid
    double offset;   // n . x = offset on the surface [m]
  };
  std::vector<Plane> planes_;
  fcl::DynamicAABBTreeCollisionManagerd manager_;
  std::vector<std::pair<int, int>> excluded_;  // sorted joint pairs that do not collide
};

}  // namespace substep

// s1, broadphase: FCL's dynamic AABB tree over all bodies, each box grown by how far its body can
// move in a step; returns the pairs whose boxes overlap, minus static-static pairs and pairs
// joined by a joint that does not let them collide.
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
  // downstream, so it is made independent of the tree's traversal.
  void findPairs(std::vector<std::pair<int, int>>& pairs);
  const CollisionShape& shape(int body) const { return shapes_[static_cast<size_t>(body)]; }

 private:
  const Model& model_;
  std::vector<CollisionShape> shapes_;
  struct Object;  // an FCL object whose box can be grown
  std::vector<std::unique_ptr<Object>> objects_;
  fcl::DynamicAABBTreeCollisionManagerd manager_;
  std::vector<std::pair<int, int>> excluded_;  // sorted joint pairs that do not collide
};

}  // namespace substep

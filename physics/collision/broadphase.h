// s1, broadphase: FCL's dynamic AABB tree over all bodies; returns the pairs whose boxes
// overlap, minus static-static pairs and pairs joined by a joint that does not let them collide.
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
  // Moves every dynamic body's FCL object to its state and refits the tree.
  void update(const State& state);
  // Overlapping pairs (i < j by body index), in increasing order. The order is the solve order
  // downstream, so it is made independent of the tree's traversal.
  void findPairs(std::vector<std::pair<int, int>>& pairs);
  const CollisionShape& shape(int body) const { return shapes_[static_cast<size_t>(body)]; }

 private:
  const Model& model_;
  std::vector<CollisionShape> shapes_;
  std::vector<std::unique_ptr<fcl::CollisionObjectd>> objects_;
  fcl::DynamicAABBTreeCollisionManagerd manager_;
  std::vector<std::pair<int, int>> excluded_;  // sorted joint pairs that do not collide
};

}  // namespace substep

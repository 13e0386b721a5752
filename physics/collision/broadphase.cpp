#include "physics/collision/broadphase.h"

#include <algorithm>

namespace substep {

struct Broadphase::Object : fcl::CollisionObjectd {
  using fcl::CollisionObjectd::CollisionObjectd;
  void grow(double d) {
    aabb.min_ -= fcl::Vector3d::Constant(d);
    aabb.max_ += fcl::Vector3d::Constant(d);
  }
};

namespace {

struct PairCollector {
  const Model* model;
  const std::vector<std::pair<int, int>>* excluded;
  std::vector<std::pair<int, int>>* pairs;
};

bool collectPair(fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data) {
  auto* c = static_cast<PairCollector*>(data);
  int i = static_cast<int>(reinterpret_cast<intptr_t>(o1->getUserData()));
  int j = static_cast<int>(reinterpret_cast<intptr_t>(o2->getUserData()));
  if (i > j) std::swap(i, j);
  const auto& bi = c->model->bodies[static_cast<size_t>(i)];
  const auto& bj = c->model->bodies[static_cast<size_t>(j)];
  if (bi.isStatic && bj.isStatic) return false;
  if (std::binary_search(c->excluded->begin(), c->excluded->end(), std::make_pair(i, j))) return false;
  c->pairs->emplace_back(i, j);
  return false;  // never stop early
}

fcl::Transform3d transformOf(const BodyState& s, const Pose& offset) {
  fcl::Transform3d t = fcl::Transform3d::Identity();
  t.linear() = (s.q * offset.q).toRotationMatrix();
  t.translation() = s.x + s.q * offset.p;
  return t;
}

}  // namespace

Broadphase::Broadphase(const Model& model) : model_(model) {
  for (size_t i = 0; i < model.bodies.size(); ++i) {
    shapes_.push_back(makeCollisionShape(model.bodies[i].shape));
    objects_.push_back(std::make_unique<Object>(shapes_.back().geometry));
    objects_.back()->setUserData(reinterpret_cast<void*>(static_cast<intptr_t>(i)));
  }
  for (const Joint& j : model.joints)
    if (!j.collide) excluded_.emplace_back(std::min(j.bodyA, j.bodyB), std::max(j.bodyA, j.bodyB));
  std::sort(excluded_.begin(), excluded_.end());
}

Broadphase::~Broadphase() = default;

void Broadphase::update(const State& state, const std::vector<double>& reach) {
  const bool first = manager_.size() == 0;
  for (size_t i = 0; i < objects_.size(); ++i) {
    if (!first && model_.bodies[i].isStatic) continue;
    objects_[i]->setTransform(transformOf(state.bodies[i], shapes_[i].offset));
    objects_[i]->computeAABB();
    objects_[i]->grow(reach[i]);
  }
  if (first) {
    std::vector<fcl::CollisionObjectd*> all;
    for (auto& o : objects_) all.push_back(o.get());
    manager_.registerObjects(all);
    manager_.setup();
  } else {
    manager_.update();
  }
}

void Broadphase::findPairs(std::vector<std::pair<int, int>>& pairs) {
  pairs.clear();
  PairCollector c{&model_, &excluded_, &pairs};
  manager_.collide(&c, collectPair);
  std::sort(pairs.begin(), pairs.end());
}

}  // namespace substep

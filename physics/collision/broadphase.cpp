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
  size_t maxPairs;
};

bool admitted(const PairCollector& c, int i, int j) {
  if (i > j) std::swap(i, j);
  const Body& bi = c.model->bodies[static_cast<size_t>(i)];
  const Body& bj = c.model->bodies[static_cast<size_t>(j)];
  if ((bi.isStatic && bj.isStatic) || !mayTouch(bi, bj)) return false;
  if (std::binary_search(c.excluded->begin(), c.excluded->end(), std::make_pair(i, j))) return false;
  c.pairs->emplace_back(i, j);
  return true;
}

bool collectPair(fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data) {
  auto* c = static_cast<PairCollector*>(data);
  const int i = static_cast<int>(reinterpret_cast<intptr_t>(o1->getUserData()));
  const int j = static_cast<int>(reinterpret_cast<intptr_t>(o2->getUserData()));
  admitted(*c, i, j);
  return c->pairs->size() > c->maxPairs;  // stop early only when over the cap
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
    const Shape& s = model.bodies[i].shape;
    shapes_.push_back(makeCollisionShape(s));
    if (s.type == ShapeType::Plane) {
      objects_.push_back(nullptr);
      continue;
    }
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
  if (first) {
    planes_.clear();
    for (size_t i = 0; i < objects_.size(); ++i) {
      if (objects_[i]) continue;
      const Shape& s = model_.bodies[i].shape;  // planes are static: placed once
      const Pose pose = state.bodies[i].pose();
      const Vec3 n = pose.rotate(s.normal).normalized();
      planes_.push_back({static_cast<int>(i), n, s.offset + n.dot(pose.p)});
    }
  }
  for (size_t i = 0; i < objects_.size(); ++i) {
    if (!objects_[i] || (!first && model_.bodies[i].isStatic)) continue;
    objects_[i]->setTransform(transformOf(state.bodies[i], shapes_[i].offset));
    objects_[i]->computeAABB();
    objects_[i]->grow(reach[i]);
  }
  if (first) {
    std::vector<fcl::CollisionObjectd*> all;
    for (auto& o : objects_)
      if (o) all.push_back(o.get());
    manager_.registerObjects(all);
    manager_.setup();
  } else {
    manager_.update();
  }
}

bool Broadphase::findPairs(std::vector<std::pair<int, int>>& pairs, size_t maxPairs) {
  pairs.clear();
  PairCollector c{&model_, &excluded_, &pairs, maxPairs};
  manager_.collide(&c, collectPair);
  // A body meets a plane when the lowest corner of its (grown) box is below the surface.
  for (const Plane& p : planes_) {
    for (size_t i = 0; i < objects_.size() && pairs.size() <= maxPairs; ++i) {
      if (!objects_[i] || model_.bodies[i].isStatic) continue;
      const auto& box = objects_[i]->getAABB();
      const Vec3 centre = 0.5 * (box.min_ + box.max_), half = 0.5 * (box.max_ - box.min_);
      if (p.n.dot(centre) - half.dot(p.n.cwiseAbs()) <= p.offset) admitted(c, static_cast<int>(i), p.body);
    }
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs.size() <= maxPairs;
}

}  // namespace substep

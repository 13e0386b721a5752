#include "physics/collision/broadphase.h"

#include <algorithm>
#include <cmath>
#include <iterator>

namespace substep {

namespace {

// An FCL object whose box we set ourselves: the fat box, not the shape's tight one.
struct FatObject : fcl::CollisionObjectd {
  using fcl::CollisionObjectd::CollisionObjectd;
  void setBox(const Vec3& lo, const Vec3& hi) {
    aabb.min_ = lo;
    aabb.max_ = hi;
  }
};

fcl::Transform3d transformOf(const BodyState& s, const Pose& offset) {
  fcl::Transform3d t = fcl::Transform3d::Identity();
  t.linear() = (s.q * offset.q).toRotationMatrix();
  t.translation() = s.x + s.q * offset.p;
  return t;
}

// How much bigger than its reach box a body's fat box is: a tenth of a metre for bodies of a
// metre and more (Box2D's margin), less for small ones, so that small bodies do not all meet.
double fatMargin(const Shape& s) { return std::clamp(0.25 * s.boundingRadius(), 1e-3, 0.1); }

// The world box of a placed shape. FCL's own (CollisionObject::computeAABB) is the box of the
// bounding sphere as soon as the rotation is not exactly the identity, which a resting box's never
// is: 1.73 times too wide for a cube, every pyramid neighbour in reach. The shape's local box
// turned by |R| is exact for boxes and for the axis-aligned faces of everything else; a sphere
// is its radius in every direction.
void tightBox(const fcl::CollisionObjectd& o, const Shape& s, Vec3& lo, Vec3& hi) {
  const fcl::Transform3d& t = o.getTransform();
  if (s.type == ShapeType::Sphere) {
    lo = t.translation() - Vec3::Constant(s.radius);
    hi = t.translation() + Vec3::Constant(s.radius);
    return;
  }
  const fcl::AABBd& local = o.collisionGeometry()->aabb_local;
  const Vec3 centre = t * local.center();
  const Vec3 half = t.linear().cwiseAbs() * (0.5 * (local.max_ - local.min_));
  lo = centre - half;
  hi = centre + half;
}

struct Query {
  const std::vector<std::unique_ptr<fcl::CollisionObjectd>>* objects;
  std::vector<std::pair<int, int>>* found;
  size_t cap;
  const void* self;
  bool (*admit)(const void*, int, int);
};

bool collectCandidate(fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data) {
  auto* q = static_cast<Query*>(data);
  int i = static_cast<int>(reinterpret_cast<intptr_t>(o1->getUserData()));
  int j = static_cast<int>(reinterpret_cast<intptr_t>(o2->getUserData()));
  if (i == j) return false;
  if (i > j) std::swap(i, j);
  if (q->admit(q->self, i, j)) q->found->emplace_back(i, j);
  return q->found->size() > q->cap;  // stop only when over the cap
}

}  // namespace

int Broadphase::rebuildExcess(int leaves) {
  return 2 * static_cast<int>(std::ceil(std::log2(std::max(2, leaves)))) + 10;
}

int Broadphase::treeHeight() const { return static_cast<int>(manager_.getTree().getMaxHeight()); }

Broadphase::Broadphase(const Model& model) : model_(model) {
  int inTree = 0;
  for (size_t i = 0; i < model.bodies.size(); ++i) {
    const Shape& s = model.bodies[i].shape;
    shapes_.push_back(makeCollisionShape(s));
    if (s.type == ShapeType::Plane) {
      objects_.push_back(nullptr);
      continue;
    }
    objects_.push_back(std::make_unique<FatObject>(shapes_.back().geometry));
    objects_.back()->setUserData(reinterpret_cast<void*>(static_cast<intptr_t>(i)));
    ++inTree;
  }
  manager_.max_tree_nonbalanced_level = rebuildExcess(inTree);
  reachBox_.resize(model.bodies.size());
  fat_.resize(model.bodies.size());
  // At most every body moves in one update: reserved, so a step in which more move than ever
  // before allocates nothing.
  movedList_.reserve(model.bodies.size());
  movedObjects_.reserve(model.bodies.size());
  for (const Joint& j : model.joints)
    if (!j.collide) excluded_.emplace_back(std::min(j.bodyA, j.bodyB), std::max(j.bodyA, j.bodyB));
  std::sort(excluded_.begin(), excluded_.end());
}

Broadphase::~Broadphase() = default;

bool Broadphase::admitted(int i, int j) const {
  const Body& bi = model_.bodies[static_cast<size_t>(i)];
  const Body& bj = model_.bodies[static_cast<size_t>(j)];
  if ((bi.isStatic && bj.isStatic) || !mayTouch(bi, bj)) return false;
  return !std::binary_search(excluded_.begin(), excluded_.end(), std::make_pair(i, j));
}

void Broadphase::update(const State& state, const std::vector<double>& reach, const std::vector<Vec3>& move,
                        const Vec3& fall, WorkerPool& pool) {
  movedList_.clear();
  if (!registered_) {
    planes_.clear();
    for (size_t i = 0; i < objects_.size(); ++i) {
      if (objects_[i]) continue;
      const Shape& s = model_.bodies[i].shape;  // planes are static: placed once
      const Pose pose = state.bodies[i].pose();
      const Vec3 n = pose.rotate(s.normal).normalized();
      planes_.push_back({static_cast<int>(i), n, s.offset + n.dot(pose.p)});
    }
  }
  // Whether body i's fat box changed; writes only body i's object and boxes.
  const auto place = [&](size_t i) {
    if (!objects_[i] || (registered_ && model_.bodies[i].isStatic)) return false;
    auto& o = static_cast<FatObject&>(*objects_[i]);
    o.setTransform(transformOf(state.bodies[i], shapes_[i].offset));
    Box& r = reachBox_[i];
    tightBox(o, model_.bodies[i].shape, r.lo, r.hi);
    r.lo -= Vec3::Constant(reach[i]);
    r.hi += Vec3::Constant(reach[i]);
    if (!model_.bodies[i].isStatic) {  // the free-flight path: inside the box of its three corners
      const Vec3 end = move[i] + fall;
      r.lo += move[i].cwiseMin(end).cwiseMin(Vec3::Zero());
      r.hi += move[i].cwiseMax(end).cwiseMax(Vec3::Zero());
    }
    if (registered_ && fat_[i].contains(r)) {
      o.setBox(fat_[i].lo, fat_[i].hi);  // unchanged in the tree
      return false;
    }
    const double m = model_.bodies[i].isStatic ? 0.0 : fatMargin(model_.bodies[i].shape);
    fat_[i] = Box{r.lo - Vec3::Constant(m), r.hi + Vec3::Constant(m)};
    o.setBox(fat_[i].lo, fat_[i].hi);
    return true;
  };
  movedNow_.resize(objects_.size());
  pool.forRange(objects_.size(), kBodyBlock, [&](size_t first, size_t last, int) {
    for (size_t i = first; i < last; ++i) movedNow_[i] = place(i);
  });
  for (size_t i = 0; i < objects_.size(); ++i)
    if (movedNow_[i]) movedList_.push_back(static_cast<int>(i));
  moved_ = static_cast<int>(movedList_.size());
  if (!registered_) {
    std::vector<fcl::CollisionObjectd*> all;
    for (auto& o : objects_)
      if (o) all.push_back(o.get());
    manager_.registerObjects(all);
    manager_.setup();
    registered_ = true;
  } else if (!movedList_.empty()) {
    movedObjects_.clear();
    for (const int i : movedList_) movedObjects_.push_back(objects_[static_cast<size_t>(i)].get());
    manager_.update(movedObjects_);
  }
}

bool Broadphase::findPairs(std::vector<std::pair<int, int>>& pairs, size_t maxPairs, WorkerPool& pool) {
  pairs.clear();
  // Candidates whose fat boxes came apart are dropped; the moved bodies' new neighbours added.
  if (!movedList_.empty()) {
    size_t keep = 0;
    for (const auto& pr : candidates_)
      if (fat_[static_cast<size_t>(pr.first)].overlaps(fat_[static_cast<size_t>(pr.second)])) candidates_[keep++] = pr;
    candidates_.resize(keep);
    // Each block of moved bodies queries the tree into its own list and sorts it; the lists are
    // then merged. The result is a sorted set, whatever the blocks and threads.
    const size_t cap = 4 * maxPairs;
    constexpr size_t kGrain = 32;
    const size_t blocks = (movedList_.size() + kGrain - 1) / kGrain;
    if (blockFound_.size() < blocks) blockFound_.resize(blocks);
    pool.forBlocks(blocks, [&](size_t b, int) {
      std::vector<std::pair<int, int>>& found = blockFound_[b];
      found.clear();
      Query q{&objects_, &found, cap, this,
              [](const void* self, int i, int j) { return static_cast<const Broadphase*>(self)->admitted(i, j); }};
      const size_t last = std::min(movedList_.size(), (b + 1) * kGrain);
      for (size_t k = b * kGrain; k < last && found.size() <= cap; ++k)
        manager_.collide(objects_[static_cast<size_t>(movedList_[k])].get(), &q, collectCandidate);
      std::sort(found.begin(), found.end());  // duplicates kept: the cap counts them, as one list would
    });
    // The blocks' sorted lists, end to end, merged pairwise bottom up (runs_: where each starts).
    found_.clear();
    runs_.assign(1, 0);
    for (size_t b = 0; b < blocks; ++b) {
      found_.insert(found_.end(), blockFound_[b].begin(), blockFound_[b].end());
      if (found_.size() > cap) return false;
      runs_.push_back(found_.size());
    }
    while (runs_.size() > 2) {
      mergeBuffer_.resize(found_.size());
      nextRuns_.assign(1, 0);
      for (size_t r = 0; r + 1 < runs_.size(); r += 2) {
        const size_t mid = runs_[r + 1], end = r + 2 < runs_.size() ? runs_[r + 2] : mid;
        std::merge(found_.begin() + static_cast<long>(runs_[r]), found_.begin() + static_cast<long>(mid),
                   found_.begin() + static_cast<long>(mid), found_.begin() + static_cast<long>(end),
                   mergeBuffer_.begin() + static_cast<long>(runs_[r]));
        nextRuns_.push_back(end);
      }
      found_.swap(mergeBuffer_);
      runs_.swap(nextRuns_);
    }
    found_.erase(std::unique(found_.begin(), found_.end()), found_.end());
    merged_.clear();
    std::set_union(candidates_.begin(), candidates_.end(), found_.begin(), found_.end(), std::back_inserter(merged_));
    candidates_.swap(merged_);
    movedList_.clear();
  }
  // Each block's pairs into its own list on the threads, the lists taken in block order: the
  // pairs (and, past maxPairs, those found so far) are the serial loop's. `into` gets the lists of
  // `blocks` blocks; false once it holds more than `cap` beyond `base` pairs.
  const auto gather = [&](size_t blocks, std::vector<std::pair<int, int>>& into, size_t base, size_t cap) {
    for (size_t b = 0; b < blocks; ++b) {
      const std::vector<std::pair<int, int>>& kept = blockFound_[b];
      if (base + into.size() + kept.size() > cap) {
        into.insert(into.end(), kept.begin(), kept.begin() + static_cast<long>(cap + 1 - base - into.size()));
        return false;
      }
      into.insert(into.end(), kept.begin(), kept.end());
    }
    return true;
  };
  // The candidates whose reach boxes overlap.
  constexpr size_t kTestGrain = 4096;
  const size_t nc = candidates_.size();
  size_t blocks = (nc + kTestGrain - 1) / kTestGrain;
  if (blockFound_.size() < blocks) blockFound_.resize(blocks);
  pool.forBlocks(blocks, [&](size_t b, int) {
    std::vector<std::pair<int, int>>& kept = blockFound_[b];
    kept.clear();
    for (size_t k = b * kTestGrain, e = std::min(nc, (b + 1) * kTestGrain); k < e; ++k)
      if (reachBox_[static_cast<size_t>(candidates_[k].first)].overlaps(reachBox_[static_cast<size_t>(candidates_[k].second)]))
        kept.push_back(candidates_[k]);
  });
  if (!gather(blocks, pairs, 0, maxPairs)) return false;
  // A body meets a plane when the lowest corner of its reach box is below the surface. Each
  // plane's pairs come in increasing order (i ascending, the plane on one side of all of them), and
  // no candidate holds a plane (planes are not in the tree): merged into the candidates' order.
  const size_t nb = objects_.size();
  planePairs_.clear();
  for (const Plane& p : planes_) {
    blocks = (nb + kBodyBlock - 1) / kBodyBlock;
    if (blockFound_.size() < blocks) blockFound_.resize(blocks);
    pool.forBlocks(blocks, [&](size_t b, int) {
      std::vector<std::pair<int, int>>& kept = blockFound_[b];
      kept.clear();
      for (size_t i = b * kBodyBlock, e = std::min(nb, (b + 1) * kBodyBlock); i < e; ++i) {
        if (!objects_[i] || model_.bodies[i].isStatic) continue;
        const Box& box = reachBox_[i];
        const Vec3 centre = 0.5 * (box.lo + box.hi), half = 0.5 * (box.hi - box.lo);
        if (p.n.dot(centre) - half.dot(p.n.cwiseAbs()) > p.offset) continue;
        const int a = std::min(static_cast<int>(i), p.body), c = std::max(static_cast<int>(i), p.body);
        if (admitted(a, c)) kept.emplace_back(a, c);
      }
    });
    if (!gather(blocks, planePairs_, pairs.size(), maxPairs)) {
      pairs.insert(pairs.end(), planePairs_.begin(), planePairs_.end());
      return false;
    }
  }
  if (planePairs_.empty()) return true;
  if (planes_.size() > 1) std::sort(planePairs_.begin(), planePairs_.end());
  merged_.clear();
  std::merge(pairs.begin(), pairs.end(), planePairs_.begin(), planePairs_.end(), std::back_inserter(merged_));
  pairs.swap(merged_);
  return true;
}

}  // namespace substep

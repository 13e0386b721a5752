#include "physics/world.h"

#include "physics/collision/contact_margin.h"
#include "physics/failure.h"
#include "physics/limits.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace substep {

namespace {

using Clock = std::chrono::steady_clock;

double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

bool isSurface(ShapeType t) { return t == ShapeType::Plane || t == ShapeType::TriangleMesh; }

}  // namespace

World::World(const Model& model, const SolverSettings& settings, const State& initial)
    : model_(model), settings_(settings), state_(initial), broadphase_(model), stepper_(makeStepper(settings.algorithm)) {
  if (state_.bodies.size() != model.bodies.size())
    throw std::invalid_argument("World: the state has " + std::to_string(state_.bodies.size()) + " bodies, the model " +
                                std::to_string(model.bodies.size()));
  for (const Body& b : model.bodies)
    if (!b.isStatic && isSurface(b.shape.type))
      throw std::invalid_argument("World: body \"" + b.name + "\": planes and triangle meshes must be static");
  ctx_.model = &model_;
  ctx_.settings = &settings_;
  ctx_.state = &state_;
  ctx_.constraints = &constraints_;
  const size_t nb = model.bodies.size();
  ctx_.mass.resize(nb);
  for (size_t i = 0; i < nb; ++i) {
    const Body& b = model.bodies[i];
    if (!b.isStatic) ctx_.mass[i] = BodyMass{b.invMass, b.invInertia};
  }
  // assign, not resize: Eigen's vectors are not zeroed by default construction.
  ctx_.poses.resize(nb);
  reach_.assign(nb, 0.0);
  move_.assign(nb, Vec3::Zero());
  approachV_.assign(nb, Vec3::Zero());
  ctx_.v.assign(nb, Vec3::Zero());
  ctx_.w.assign(nb, Vec3::Zero());
  setSettings(settings);
}

bool World::dormant(int body) const {
  return model_.bodies[static_cast<size_t>(body)].isStatic || (!asleep_.empty() && asleep_[static_cast<size_t>(body)]);
}

void World::wake(int body) {
  if (asleep_.empty() || !asleep_[static_cast<size_t>(body)]) return;
  allAsleep_ = false;
  const int island = sleepIsland_[static_cast<size_t>(body)];
  for (size_t i = 0; i < asleep_.size(); ++i)
    if (asleep_[i] && sleepIsland_[i] == island) {
      asleep_[i] = 0;
      still_[i] = 0;
      ctx_.mass[i] = BodyMass{model_.bodies[i].invMass, model_.bodies[i].invInertia};
    }
}

void World::wakeTouched() {
  // Until nothing more wakes: a woken island may touch another sleeping one.
  for (bool woke = true; woke;) {
    woke = false;
    for (const Manifold& m : manifolds_.manifolds()) {
      if (m.count == 0) continue;
      const bool sa = asleep(m.a), sb = asleep(m.b);
      if (sa == sb) continue;  // both awake, or both asleep
      const int sleeper = sa ? m.b : m.a, sleeping = sa ? m.a : m.b;
      if (model_.bodies[static_cast<size_t>(sleeper)].isStatic) continue;
      wake(sleeping);
      woke = true;
    }
  }
}

void World::updateSleep() {
  const size_t nb = model_.bodies.size();
  // Islands of awake dynamic bodies joined by touching contacts (union-find); an island with a
  // joint never sleeps.
  std::vector<int> parent(nb);
  for (size_t i = 0; i < nb; ++i) parent[i] = static_cast<int>(i);
  auto find = [&](int i) {
    while (parent[static_cast<size_t>(i)] != i) i = parent[static_cast<size_t>(i)] = parent[static_cast<size_t>(parent[static_cast<size_t>(i)])];
    return i;
  };
  auto join = [&](int a, int b) {
    a = find(a), b = find(b);
    if (a != b) parent[static_cast<size_t>(std::max(a, b))] = std::min(a, b);
  };
  for (const Manifold& m : manifolds_.manifolds())
    if (m.count > 0 && !dormant(m.a) && !dormant(m.b)) join(m.a, m.b);
  std::vector<char> jointed(nb, 0);
  for (const Joint& j : model_.joints) {
    if (!dormant(j.bodyA) && !dormant(j.bodyB)) join(j.bodyA, j.bodyB);
    for (int b : {j.bodyA, j.bodyB})
      if (!model_.bodies[static_cast<size_t>(b)].isStatic) jointed[static_cast<size_t>(b)] = 1;
  }
  const double dt = settings_.dt;
  std::vector<double> leastStill(nb, INFINITY);
  std::vector<char> islandJointed(nb, 0);
  for (size_t i = 0; i < nb; ++i) {
    if (dormant(static_cast<int>(i))) continue;
    const BodyState& s = state_.bodies[i];
    const bool still = s.v.norm() < kSleepLinear && s.w.norm() < kSleepAngular;
    still_[i] = still ? still_[i] + dt : 0;
    const size_t r = static_cast<size_t>(find(static_cast<int>(i)));
    leastStill[r] = std::min(leastStill[r], still_[i]);
    islandJointed[r] = islandJointed[r] || jointed[i];
  }
  for (size_t i = 0; i < nb; ++i) {
    if (dormant(static_cast<int>(i))) continue;
    const size_t r = static_cast<size_t>(find(static_cast<int>(i)));
    if (islandJointed[r] || leastStill[r] < kTimeToSleep) continue;
    asleep_[i] = 1;
    sleepIsland_[i] = static_cast<int>(r);
    state_.bodies[i].v.setZero();
    state_.bodies[i].w.setZero();
    ctx_.mass[i] = BodyMass{};  // as a static body to the steppers, until woken
  }
  int count = 0;
  for (char a : asleep_) count += a;
  report_.asleep = count;
  allAsleep_ = count > 0 && count == model_.dynamicCount();
}

World::~World() = default;

void World::setSettings(const SolverSettings& settings) {
  // A1 keeps the position error in its MLCP's β (proc1:4) and never splits it off, so it would
  // step the coordinates with pseudo-velocities no solve of its made. Refused before anything
  // changes, as resolve() refuses a setting an algorithm does not take ("field: why").
  if (settings.splitImpulse && settings.algorithm == Algorithm::A1)
    throw std::invalid_argument(
        "split_impulse: a1 solves position error in its MLCP's bias; split impulse is an option of a2-a5 (turn it off "
        "or choose --algo a2)");
  if (settings.algorithm != settings_.algorithm) stepper_ = makeStepper(settings.algorithm);
  if (!pool_ || poolAsked_ != settings.threads) {
    pool_ = std::make_unique<WorkerPool>(settings.threads);  // may hold fewer (physics/parallel.h)
    poolAsked_ = settings.threads;
    narrowphases_.resize(static_cast<size_t>(pool_->threads()));
    ctx_.pool = pool_.get();
    constraints_.setPool(pool_.get());
  }
  settings_ = settings;
  const size_t nb = model_.bodies.size();
  // The pseudo-velocities are one step's (splitPositionErrors writes them, s4 adds them): a
  // stepper that never splits (A1, soft) must not go on adding the last split step's.
  ctx_.pseudoV.assign(nb, Vec3::Zero());
  ctx_.pseudoW.assign(nb, Vec3::Zero());
  ctx_.subV.assign(nb * static_cast<size_t>(settings.substeps), Vec3::Zero());
  ctx_.subW.assign(nb * static_cast<size_t>(settings.substeps), Vec3::Zero());
}

bool World::geometry() {
  // Where each body can get in this step in free flight: x + t h v + c h² g with 0 <= c <= t <= 1
  // under every algorithm (sub-steps included), inside the box of {0, h v, h v + h² g}; plus
  // what turning moves a point, h |w| r, and half the contact margin on every side. A pair is
  // examined when its bodies can meet, and speculative points cover the gap they can close.
  const double h = settings_.dt;
  const Vec3 fall = settings_.speculative ? Vec3(h * h * model_.gravity) : Vec3::Zero();
  eachBody([&](size_t i) {
    const Body& b = model_.bodies[i];
    const BodyState& s = state_.bodies[i];
    const bool moves = !b.isStatic && settings_.speculative;
    reach_[i] = 0.5 * kContactMargin + (moves ? h * s.w.norm() * b.shape.boundingRadius() : 0.0);
    move_[i] = moves ? Vec3(h * s.v) : Vec3::Zero();
  });
  broadphase_.update(state_, reach_, move_, fall, *pool_);
  const size_t cap = std::max<size_t>(limits::kMinPairCap, limits::kMaxPairsPerBody * model_.bodies.size());
  if (!broadphase_.findPairs(pairs_, cap, *pool_)) {
    report_.finite = false;
    report_.overloaded = true;
    report_.problem = "more than " + std::to_string(cap) + " pairs of bodies overlap (" +
                      std::to_string(limits::kMaxPairsPerBody) +
                      " per body): bodies start inside each other, or the scene has collapsed into one heap";
    return false;
  }
  manifolds_.beginStep(true);
  // Each pair's manifold on the step's threads, a block of pairs at a time into the block's own
  // list (a kept one by its place in last step's); the lists are then taken in block order, so
  // the manifolds and the ids of new points are the same for any number of threads. Last step's
  // manifold of each pair is found by a merge, in pair order, each block's from where its first
  // pair would be.
  const size_t np = pairs_.size();
  constexpr size_t kPairBlock = 64;
  const size_t blocks = (np + kPairBlock - 1) / kPairBlock;
  if (pairBlocks_.size() < blocks) pairBlocks_.resize(blocks);
  pool_->forBlocks(blocks, [&](size_t blk, int thread) {
    std::vector<Manifold>& out = pairBlocks_[blk].made;
    std::vector<int>& from = pairBlocks_[blk].from;
    out.clear();
    from.clear();
    int points = 0;
    int cached = 0, fresh = 0;
    // Where the block's kept manifolds stood in last step's list, less their places in the
    // block: one value when they all stand as they stood (then in place if the block starts there).
    int shift = PairBlock::kNoneKept;
    const auto keptAt = [&](size_t was) {
      const int d = static_cast<int>(was) - static_cast<int>(from.size() - 1);
      shift = shift == PairBlock::kNoneKept || shift == d ? d : PairBlock::kMixed;
    };
    ContactPatch patch;
    const size_t first = blk * kPairBlock, last = std::min(np, (blk + 1) * kPairBlock);
    size_t cursor = manifolds_.start(pairs_[first].first, pairs_[first].second);
    for (size_t k = first; k < last; ++k) {
      // A plane or triangle mesh is always B, so the normal points out of it.
      auto& [i, j] = pairs_[k];
      if (isSurface(model_.bodies[static_cast<size_t>(i)].shape.type)) std::swap(i, j);
      const int a = i, b = j;
      const Body& A = model_.bodies[static_cast<size_t>(a)];
      const Body& B = model_.bodies[static_cast<size_t>(b)];
      const Pose pA = state_.bodies[static_cast<size_t>(a)].pose();
      const Pose pB = state_.bodies[static_cast<size_t>(b)].pose();
      // A pair that has barely moved relative to itself since its points were found keeps them; a
      // pair of which neither body moves (static or asleep) keeps them too, for when it wakes.
      const Manifold* old = manifolds_.previous(a, b, cursor);
      if (old && ((!asleep_.empty() && dormant(a) && dormant(b)) || pairShiftBelow(*old, pA, pB, kPairCacheShift))) {
        from.push_back(static_cast<int>(cursor));  // previous() leaves the cursor on it
        keptAt(cursor);
        points += old->count;
        ++cached;
        continue;
      }
      // The gap the pair can close: relative motion, in which gravity cancels unless one is static
      // (bodies falling side by side never meet, however fast they fall).
      const double fallRel = A.isStatic == B.isStatic ? 0.0 : fall.norm();
      const double gapLimit = reach_[static_cast<size_t>(a)] + reach_[static_cast<size_t>(b)] +
                              (move_[static_cast<size_t>(a)] - move_[static_cast<size_t>(b)]).norm() + fallRel;
      narrowphases_[static_cast<size_t>(thread)].collide(A.shape, broadphase_.shape(a), pA, B.shape,
                                                         broadphase_.shape(b), pB, gapLimit, patch);
      if (patch.count == 0) continue;
      // How far from its origin a point of B can be: B's size, or for a surface the distance of A's
      // far side from B's origin.
      const double rA = A.shape.boundingRadius();
      const double rB = isSurface(B.shape.type) ? (pA.p - pB.p).norm() + rA : B.shape.boundingRadius();
      out.emplace_back();
      ManifoldCache::made(out.back(), a, b, pA, pB, std::sqrt(A.friction * B.friction),
                          std::max(A.restitution, B.restitution), patch, rB, old);
      fresh += newPoints(out.back());
      points += out.back().count;
      from.push_back(-static_cast<int>(out.size()));
    }
    pairBlocks_[blk].shift = shift;
    pairBlocks_[blk].cached = cached;  // once: threads counting into neighbouring blocks would share a cache line
    pairBlocks_[blk].fresh = fresh;
    pairBlocks_[blk].points = points;
  });
  // Where each block's manifolds go and the id its first new point takes; then placed.
  size_t at = 0;
  uint32_t fresh = 0;
  report_.cachedPairs = 0;
  report_.contactPoints = 0;
  bool inPlace = true;  // every manifold kept in its place in last step's list
  for (size_t blk = 0; blk < blocks; ++blk) {
    PairBlock& b = pairBlocks_[blk];
    b.at = at;
    b.firstId = fresh;
    inPlace = inPlace && (b.shift == PairBlock::kNoneKept || b.shift == static_cast<int>(at));
    at += b.from.size();
    fresh += static_cast<uint32_t>(b.fresh);
    report_.cachedPairs += b.cached;
    report_.contactPoints += b.points;
  }
  inPlace = inPlace && at == manifolds_.lastStep().size();
  const uint32_t firstId = manifolds_.claimIds(fresh);
  // In place (a settled scene, or one where a few pairs were made again): last step's list is
  // this step's, a kept manifold aged where it is rather than copied (816 bytes; 8 MB a step on
  // the 100-level pyramid), a made one written over whichever stood in its place.
  std::vector<Manifold>& placed = inPlace ? manifolds_.keepInPlace() : manifolds_.place(at, *pool_);
  pool_->forBlocks(blocks, [&](size_t blk, int) {
    const PairBlock& b = pairBlocks_[blk];
    uint32_t id = firstId + b.firstId;
    Manifold* to = placed.data() + b.at;
    for (const int k : b.from) {
      if (k < 0) {
        *to = b.made[static_cast<size_t>(-1 - k)];
        id = numberNewPoints(*to, id);
      } else if (inPlace) {
        ManifoldCache::aged(*to);
      } else {
        ManifoldCache::kept(*to, manifolds_.lastStep()[static_cast<size_t>(k)]);
      }
      ++to;
    }
  });
  report_.pairs = static_cast<int>(pairs_.size());
  report_.manifolds = static_cast<int>(manifolds_.manifolds().size());
  return true;
}

const std::vector<Manifold>& World::solvedManifolds() {
  if (asleep_.empty()) return manifolds_.manifolds();
  // Only pairs with an awake dynamic body: a pair of sleeping (or static) bodies has no row.
  active_.clear();
  activeAt_.clear();
  const std::vector<Manifold>& all = manifolds_.manifolds();
  for (size_t k = 0; k < all.size(); ++k)
    if (!dormant(all[k].a) || !dormant(all[k].b)) {
      active_.push_back(all[k]);
      activeAt_.push_back(k);
    }
  return active_;
}

void World::formulate() {
  eachBody([&](size_t i) {
    ctx_.poses[i] = state_.bodies[i].pose();
    ctx_.v[i] = state_.bodies[i].v;
    ctx_.w[i] = state_.bodies[i].w;
  });
  const double hSub = settings_.dt / settings_.substeps;
  const double applyScale = settings_.algorithm == Algorithm::A5 ? settings_.kappa : 1.0;
  constraints_.askDeferredContactRows(stepper_->formulatesContactRows(settings_));
  constraints_.askLaneGroups(stepper_->asksLaneGroups(settings_, pool_->threads()));
  constraints_.build(model_, solvedManifolds(), ctx_.poses, ctx_.mass, settings_, hSub, applyScale);
  // The approach speed restitution reflects: the contact's at the end of this step in free flight
  // (v + h g), nearer the speed of impact within the step than Box2D's at its start. A ball dropped
  // 1 m rebounds to 0.92 e² of its height under A1/A2 at h = 1/60 this way (0.85 with the start's),
  // 0.97 under A3-A5 and soft (tests/test_contacts.cpp).
  const Vec3 gh = settings_.dt * model_.gravity;
  eachBody([&](size_t i) { approachV_[i] = ctx_.mass[i].invMass > 0 ? Vec3(ctx_.v[i] + gh) : ctx_.v[i]; });
  constraints_.recordApproach(approachV_.data(), ctx_.w.data());
}

bool World::diverged() {
  // What is wrong with body i's state (null: nothing), and the value that is.
  const auto check = [&](size_t i, double& value) -> const char* {
    const BodyState& b = state_.bodies[i];
    value = 0;
    // Every body, twice a step: first without a square root. |x|² <= 1e12 holds only for finite
    // x with |x| <= 1e6 (sqrt is monotonic and sqrt(1e12) is 1e6); anything else is looked at below.
    constexpr double kCoord2 = kMaxCoordinate * kMaxCoordinate, kSpeed2 = kMaxSpeed * kMaxSpeed;
    if (b.x.squaredNorm() <= kCoord2 && b.v.squaredNorm() <= kSpeed2 && b.w.squaredNorm() <= kSpeed2 &&
        std::isfinite(b.q.w()) && allFinite(b.q.vec()))
      return nullptr;
    if (!allFinite(b.x) || !allFinite(b.v) || !allFinite(b.w) || !std::isfinite(b.q.w()) || !allFinite(b.q.vec()))
      return "a non-finite coordinate or velocity";
    if ((value = b.x.norm()) > kMaxCoordinate) return "a position beyond 1e6 m";
    if ((value = std::max(b.v.norm(), b.w.norm())) > kMaxSpeed) return "a speed beyond 1e6 m/s or rad/s";
    return nullptr;
  };
  // The first such body, whatever the threads: each block's first, then the lowest of those.
  const size_t nb = state_.bodies.size();
  firstBad_.assign((nb + kBodyBlock - 1) / kBodyBlock, nb);
  pool_->forRange(nb, kBodyBlock, [&](size_t first, size_t last, int) {
    double value;
    for (size_t i = first; i < last; ++i)
      if (check(i, value)) {
        firstBad_[first / kBodyBlock] = i;
        return;
      }
  });
  const size_t i = firstBad_.empty() ? nb : *std::min_element(firstBad_.begin(), firstBad_.end());
  if (i == nb) return false;
  double value;
  const char* what = check(i, value);
  report_.finite = false;
  report_.problem = "body \"" + model_.bodies[i].name + "\" has " + what;
  if (value > 0) report_.problem += " (" + std::to_string(value) + ")";
  return true;
}

const StepReport& World::step() {
  report_.finite = true;
  report_.overloaded = false;
  report_.problem.clear();
  if (diverged()) return report_;  // FCL's AABB tree crashes on such boxes
  auto t0 = Clock::now();
  if (settings_.sleep && asleep_.empty()) {
    asleep_.assign(model_.bodies.size(), 0);
    sleepIsland_.assign(model_.bodies.size(), -1);
    still_.assign(model_.bodies.size(), 0.0);
  }
  if (!settings_.sleep && !asleep_.empty()) {  // turned off: everyone awake
    for (size_t i = 0; i < asleep_.size(); ++i) wake(static_cast<int>(i));
    asleep_.clear();
    allAsleep_ = false;
  }
  if (allAsleep_) {  // nothing moves and nothing can touch: the last step's manifolds stand
    report_.times = StageTimes{};
    report_.solver = StepStats{};
    state_.time += settings_.dt;
    state_.step += 1;
    return report_;
  }
  const WorkerPool::Busy busy(*pool_);  // the step's workers stay awake between its jobs
  if (!geometry()) return report_;
  if (!asleep_.empty()) wakeTouched();
  report_.times.s1 = since(t0);

  t0 = Clock::now();
  formulate();
  report_.times.s2 = since(t0);

  t0 = Clock::now();
  stepper_->stepVelocities(ctx_);
  report_.times.s3 = since(t0);

  t0 = Clock::now();
  stepper_->stepCoordinates(ctx_);
  report_.times.s4 = since(t0);

  if (asleep_.empty()) {
    constraints_.storeImpulses(manifolds_.manifolds());
  } else {
    constraints_.storeImpulses(active_);
    for (size_t k = 0; k < active_.size(); ++k) manifolds_.manifolds()[activeAt_[k]] = active_[k];
    updateSleep();
  }
  report_.solver = ctx_.stats;
  total_ += report_.times;
  state_.time += settings_.dt;
  state_.step += 1;
  diverged();
  return report_;
}

void World::applyImpulse(int body, const Vec3& impulse, const Vec3& worldPoint) {
  if (body < 0 || body >= static_cast<int>(model_.bodies.size()))
    throw std::invalid_argument("applyImpulse: no body " + std::to_string(body));
  const Body& b = model_.bodies[static_cast<size_t>(body)];
  if (b.isStatic) throw std::invalid_argument("applyImpulse: body \"" + b.name + "\" is static");
  if (!allFinite(impulse) || !allFinite(worldPoint)) throw std::invalid_argument("applyImpulse: not finite");
  BodyState& s = state_.bodies[static_cast<size_t>(body)];
  wake(body);
  s.v += b.invMass * impulse;
  s.w += b.invInertia.cwiseProduct(s.q.conjugate() * (worldPoint - s.x).cross(impulse));  // v̌: body frame
}

RayHit World::raycast(const Vec3& origin, const Vec3& direction, double maxDistance, bool dynamicOnly) const {
  return substep::raycast(model_, state_, origin, direction, maxDistance, dynamicOnly);
}

double World::kineticEnergy() const { return substep::kineticEnergy(model_, state_); }

double World::potentialEnergy() const { return substep::potentialEnergy(model_, state_); }

double World::maxPenetration() const {
  std::vector<Pose> poses(state_.bodies.size());
  for (size_t i = 0; i < poses.size(); ++i) poses[i] = state_.bodies[i].pose();
  return constraints_.maxPenetration(poses);
}

double World::maxJointError() const {
  std::vector<Pose> poses(state_.bodies.size());
  for (size_t i = 0; i < poses.size(); ++i) poses[i] = state_.bodies[i].pose();
  return constraints_.maxJointError(poses);
}

}  // namespace substep

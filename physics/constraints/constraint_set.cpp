#include "physics/constraints/constraint_set.h"

#include "physics/constraints/joints.h"
#include "physics/step_arrays.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <stdexcept>

namespace substep {

namespace {

// x / n, as a product by 1/n where that is exact (n = 1, 2, 4: four points is the usual
// manifold, and three divisions a point were a measurable part of formulating it).
struct Share {
  explicit Share(int count) : n(count), inv(1.0 / count), exact((count & (count - 1)) == 0) {}
  template <class T>
  T operator()(const T& x) const {
    return exact ? T(x * inv) : T(x / n);
  }
  int n;
  double inv;
  bool exact;
};

}  // namespace

void ConstraintSet::definePoint(const Manifold& m, const ManifoldPoint& p, bool worldFrame, ContactDef& c) {
  c.a = m.a;
  c.b = m.b;
  c.localA = p.localA;
  c.localB = p.localB;
  c.localN = p.localN;
  c.worldFrame = worldFrame;
  c.worldN = p.worldN;
  c.armA = p.armA;
  c.armB = p.armB;
  c.row = -1;
  c.restitution = m.restitution;
  c.approach = 0;  // recordApproach's
  c.lastLambda = p.lambda;
}

void ConstraintSet::build(const Model& model, const std::vector<Manifold>& manifolds, const std::vector<Pose>& poses,
                          const std::vector<BodyMass>& mass, const SolverSettings& settings, double h,
                          double applyScale) {
  model_ = &model;
  built_ = &manifolds;
  slop_ = settings.slop;
  stableBlocks_ = settings.blockSolve;
  motorUnscaled_ = settings.motorUnscaled;
  contactBlocks_ = settings.contactBlocks;
  speculative_ = settings.speculative;
  units.clear();
  blocks.clear();
  joints.clear();

  if (jointLambdaFirst_.size() != model.joints.size()) {
    jointLambdaFirst_.clear();
    int total = 0;
    for (const Joint& j : model.joints) {
      jointLambdaFirst_.push_back(total);
      total += jointLayout(j).rows;
    }
    jointLambda_.assign(static_cast<size_t>(total), 0.0);
  }
  // Per manifold on the step's threads: its points (summed below into where its first one goes),
  // whether its pair bounces and, coloured, what the colouring reads of it; and per body the frame
  // the contacts are formulated at. On the calling thread alone the manifolds' part took 0.1 ms a
  // step of the 100-level pyramid, long enough for the other thread to fall asleep before the next
  // job (docs/benchmarks.md, "s2's serial parts").
  const size_t nm = manifolds.size(), nb = poses.size();
  const bool coloured = settings.algorithm == Algorithm::Soft && settings.colours;
  manifoldPoint_.resize(nm + 1);
  bounces_.resize(nm);
  colourKey_.resize(coloured ? nm : 0);
  frames_.resize(nb);
  constexpr size_t kGrain = 1024;
  const size_t manifoldBlocks = (nm + kGrain - 1) / kGrain, bodyBlocks = (nb + kGrain - 1) / kGrain;
  parallel(manifoldBlocks + bodyBlocks, 1, [&](size_t firstBlock, size_t lastBlock) {
    for (size_t block = firstBlock; block < lastBlock; ++block) {
      if (block >= manifoldBlocks) {
        const size_t first = (block - manifoldBlocks) * kGrain, last = std::min(nb, first + kGrain);
        for (size_t i = first; i < last; ++i) frames_[i] = Frame(poses[i]);
        continue;
      }
      const size_t first = block * kGrain, last = std::min(nm, first + kGrain);
      for (size_t k = first; k < last; ++k) {
        const Manifold& m = manifolds[k];
        manifoldPoint_[k + 1] = m.count;
        bounces_[k] = m.restitution != 0;
        if (coloured) colourKey_[k] = colourKey(m.a, m.b, mass);
      }
    }
  });
  manifoldPoint_[0] = 0;
  bool bounces = false;
  for (size_t k = 0; k < nm; ++k) {
    manifoldPoint_[k + 1] += manifoldPoint_[k];
    bounces |= bounces_[k] != 0;
  }
  // Every row of the step, taken in order by `take`. The vector keeps last step's rows and each
  // is reset field by field, without a zero fill of the whole row (docs/benchmarks.md).
  // Deferred (no contact row stored): the soft step's lanes formulate them, or A5's lane groups
  // hold them, where nothing but the sweeps reads a contact's row (no joints, no restitution,
  // warm started; A5's groups: contact blocks and no split impulses).
  const bool a5Groups = laneGroupParts_ > 0 && lanesAsked_ && applyScale > 0 && contactBlocks_ && !settings.splitImpulse;
  deferred_ = (deferAsked_ || a5Groups) && model.joints.empty() && settings.warmStart && !bounces;
  resizeRewritten(rows, jointLambda_.size() + (deferred_ ? 0 : static_cast<size_t>(manifoldPoint_[nm]) + 3 * nm), workers());
  size_t next = 0;
  auto take = [&](int n) {
    Row* r = rows.data() + next;
    for (int k = 0; k < n; ++k) resetRow(r[k]);
    next += static_cast<size_t>(n);
    return r;
  };

  for (size_t k = 0; k < model.joints.size(); ++k) {
    const Joint& j = model.joints[k];
    const JointLayout layout = jointLayout(j);
    JointRef ref;
    ref.joint = static_cast<int>(k);
    ref.first = static_cast<int>(next);
    ref.count = layout.rows;
    take(ref.count);
    formulateJoint(ref, poses, h, false);
    for (int i = 0; i < ref.count; ++i)
      rows[static_cast<size_t>(ref.first + i)].lambda =
          settings.warmStart ? jointLambda_[static_cast<size_t>(jointLambdaFirst_[k] + i)] : 0.0;
    // A stable part is one block when block solving, else one unit per row; bounded rows
    // (limits, motors) are always on their own.
    ref.firstUnit = static_cast<int>(units.size());
    for (int p = 0; p < layout.parts; ++p) {
      const JointPart& part = layout.part[p];
      if (part.stable && stableBlocks_ && part.size > 1) {
        units.push_back(SolveUnit{ref.first + part.offset, part.size, SolveUnit::Stable, -1});
      } else {
        for (int i = 0; i < part.size; ++i) units.push_back(SolveUnit{ref.first + part.offset + i, 1});
      }
    }
    ref.units = static_cast<int>(units.size()) - ref.firstUnit;
    joints.push_back(ref);
  }

  // Per manifold: its points' normal rows, then its three friction rows, at places known from
  // the point counts, so that the manifolds are formulated on the step's threads, each writing
  // only its own rows and definitions.
  contactFirstRow = static_cast<int>(next);
  manifoldRow_.resize(nm + 1);
  // The rows: in manifold order, or coloured, by ascending colour (each colour's in manifold
  // order), so that a colour's rows are one block of memory.
  colourManifolds(mass.size(), coloured);
  int at = static_cast<int>(next);
  for (size_t q = 0; q < nm; ++q) {
    const size_t k = colourStart.empty() ? q : static_cast<size_t>(colourOrder[q]);
    manifoldRow_[k] = at;
    at += manifoldPoint_[k + 1] - manifoldPoint_[k] + 3;
  }
  manifoldRow_[nm] = at;
  resizeRewritten(frictions, nm, workers());  // every element written below
  // Manifold k's friction unit's, written below (finishAll numbers them so), or deferred never read.
  resizeRewritten(couplings, nm, workers());
  // Every field written below; deferred, none (eachContact defines them from the manifolds).
  resizeRewritten(contacts, deferred_ ? 0 : static_cast<size_t>(manifoldPoint_[nm]), workers());
  const bool worldFrame = worldFrame_ = settings.contactFrame == ContactFrame::World;
  warm_ = settings.warmStart;
  exempt_ = settings.frictionExempt;
  mass_ = &mass;
  h_ = h;
  applyScale_ = applyScale;
  // Stored rows are formulated eight manifolds at a time in SIMD lanes (contact_lanes.cpp), the
  // same numbers as formulateManifold's; with contact blocks, their K and K⁻¹ too.
  const bool groupsOnly = deferred_ && !deferAsked_;  // A5's groups hold the contact rows
  const bool inLanes = inLanes_ = (!deferred_ || groupsOnly) && lanesAsked_ && applyScale > 0 && nm > 0;
  blocksInLanes_ = inLanes && contactBlocks_;
  if (blocksInLanes_) resizeRewritten(laneBlocks_, nm, workers());
  // A5's lanes: the definitions first, then the groups in the runs' order. With rows stored
  // beside them, only while the groups fit in the core's L2 cache (about 1 KB a manifold; the
  // 20-level pyramid's 400 manifolds do, the 40-level one's 1640 do not): formulated in the runs'
  // order the rows are written out of order, and beyond L2 that cost more than the lanes save
  // (docs/benchmarks.md).
  const bool grouped = inLanes && laneGroupParts_ > 0 && settings.warmStart && contactBlocks_ && model.joints.empty() &&
                       (groupsOnly || !LaneRuns::outgrowsL2(nm * sizeof(lanes::RigidGroup) / lanes::kLanes));
  if (!grouped) {
    laneGroups_.clear();
    lanePartGroups_.clear();
    runCount_ = 0;
  }
  parallel(nm, 32, [&](size_t first, size_t last) {
    for (size_t mk = first; mk < last; ++mk) {
      const Manifold& m = manifolds[mk];
      FrictionDef f;
      f.a = m.a;
      f.b = m.b;
      f.mu = m.friction;
      f.firstNormal = manifoldRow_[mk];
      f.normalCount = m.count;
      Vec3 normalSum = Vec3::Zero(), worldNormalSum = Vec3::Zero();
      const Share share(m.count);
      for (int k = 0; k < m.count; ++k) {
        const ManifoldPoint& p = m.points[k];
        // Deferred, no row reads a point's definition: the lanes read the point itself.
        if (!deferred_) {
          ContactDef& c = contacts[static_cast<size_t>(manifoldPoint_[mk] + k)];
          definePoint(m, p, worldFrame, c);
          c.row = manifoldRow_[mk] + k;
        }
        f.localA += share(p.localA);  // the centroids
        f.localB += share(p.localB);
        f.armA += share(p.armA);
        f.armB += share(p.armB);
        normalSum += p.localN;
        worldNormalSum += p.worldN;
      }
      f.localN = normalSum.normalized();
      f.worldFrame = worldFrame;
      f.worldN = worldNormalSum.normalized();
      for (int k = 0; k < m.count; ++k) f.radius += share((m.points[k].localA - f.localA).norm());
      f.row = manifoldRow_[mk] + m.count;
      f.qB = poses[static_cast<size_t>(m.b)].q;
      f.lastImpulse = m.frictionImpulse;
      f.lastTwist = m.twistImpulse;
      frictions[mk] = f;
      // The rows, M̌⁻¹J̌ᵀ, the effective masses and the friction coupling while the definitions are
      // in cache, not in a pass over every row afterwards (finishAll does the joints').
      if (!deferred_ && !inLanes) formulateManifold(mk, rows.data() + manifoldRow_[mk], couplings[mk]);
    }
    if (inLanes && !grouped) formulateManifoldsInLanes(first, last);
  });
  // A5 solves island by island; the soft step, uncoloured, shares the islands out among its
  // threads (coloured, the colours share the manifolds out).
  // In lanes (SolverSettings::lanes) it goes by levels and reads no island.
  const bool softLanes = settings.lanes && settings.contactOrder == ContactOrder::Manifold;
  const bool softIslands =
      settings.algorithm == Algorithm::Soft && !softLanes && colourStart.empty() && pool_ && pool_->threads() > 1;
  // A5 in lanes sweeps every group at once on one thread; on more its stepper reads the islands'
  // sizes, and its groups may be laid out by them.
  const bool a5Islands = settings.islands && settings.algorithm == Algorithm::A5 && !(groupsOnly && workers().threads() == 1);
  // Deferred, no unit or row is listed per island: the islands follow from the definitions alone,
  // and can lay out the groups.
  if (deferred_) findIslands(a5Islands || softIslands);
  if (grouped) formulateLaneGroups();
  bouncing.clear();
  for (size_t k = 0; k < nm && bounces; ++k)
    if (bounces_[k])
      for (int p = manifoldPoint_[k]; p < manifoldPoint_[k + 1]; ++p) bouncing.push_back(p);
  // Solve order: joints, then the contacts by contactOrder (unitOrder()). Split: every contact's
  // normal row, then the friction rows; with friction interleaved, Gauss-Seidel spends its sweeps
  // on friction before the normal impulses that bound it exist: a 5-box stack under A2 at 10
  // iterations falls over; normals first hold it. Warm started, friction first: the normals then
  // act last on the velocities the step keeps. Manifold: each manifold's normal rows, then its
  // friction, as Box2D and Box3D solve them: under the soft step the 100-level pyramid's first
  // second settles instead of rocking apart (docs/algorithms.md, "The soft step at scale").
  // With block solving, a manifold's normal rows are one contact block: Gauss-Seidel row by row
  // over four coplanar points overshoots in rotation, and with one sweep per sub-step a pyramid
  // rocks itself apart (docs/algorithms.md).
  unitOrder_ = settings.contactOrder == ContactOrder::Manifold ? UnitOrder::Manifold
               : settings.warmStart                            ? UnitOrder::FrictionFirst
                                                               : UnitOrder::NormalsFirst;
  auto normalUnits = [&](FrictionDef& f) {
    f.firstNormalUnit = static_cast<int>(units.size());
    if (contactBlocks_ && f.normalCount > 1) {
      f.unit = static_cast<int>(units.size());
      units.push_back(SolveUnit{f.firstNormal, f.normalCount, SolveUnit::Contact, -1});
    } else {
      for (int k = 0; k < f.normalCount; ++k) units.push_back(SolveUnit{f.firstNormal + k, 1});
    }
  };
  auto frictionUnit = [&](FrictionDef& f) {
    f.frictionUnit = static_cast<int>(units.size());
    units.push_back(SolveUnit{f.row, 3, SolveUnit::Friction, -1});
  };
  // Deferred, the lanes solve the manifolds: no contact unit refers to a row not stored.
  if (!deferred_) forEachContactUnit(frictions, unitOrder_, normalUnits, frictionUnit);
  finishAll(mass, applyScale, true);
  // The active set each contact block ended the last step with is where this step's starts.
  for (size_t k = 0; k < frictions.size() && !blocks.empty(); ++k)
    if (frictions[k].unit >= 0) {
      BlockData& d = blocks[static_cast<size_t>(units[static_cast<size_t>(frictions[k].unit)].block)];
      if (blocksInLanes_) d = laneBlocks_[k];
      d.lastMask = manifolds[k].blockMask;
    }
  // A lane's block: its unit's, or with no unit (the groups hold the rows) its manifold's own.
  for (lanes::RigidGroup& g : laneGroups_)
    for (int l = 0; l < g.count; ++l) {
      const size_t k = static_cast<size_t>(g.manifold[l]);
      const FrictionDef& f = frictions[k];
      if (f.unit >= 0) g.block[l] = units[static_cast<size_t>(f.unit)].block;
      if (groupsOnly && blocksInLanes_ && f.normalCount > 1) {
        laneBlocks_[k].lastMask = manifolds[k].blockMask;
        g.block[l] = static_cast<int>(k);
      }
    }
  if (!deferred_) findIslands(a5Islands || softIslands);
}

void ConstraintSet::formulateManifold(size_t mk, Row* r, FrictionCoupling& coupling) const {
  // From the definitions alone, not the manifold: a caller taking the manifolds out of their order
  // reads these few contiguous lines, not the manifold's 816 bytes as well.
  const FrictionDef& f = frictions[mk];
  const Frame& A = frames_[static_cast<size_t>(f.a)];
  const Frame& B = frames_[static_cast<size_t>(f.b)];
  const int count = f.normalCount;
  for (int k = 0; k < count + 3; ++k) resetRowState(r[k]);  // the rest: formulated and finished below
  const auto point = [&](const ContactDef& c, Row& row) {
    formulateContact(c, A, B, h_, slop_, row, false);
    row.lambda = warm_ ? c.lastLambda : 0.0;
    markApart(row, speculative_);
  };
  for (int k = 0; k < count; ++k) {
    if (!deferred_) {
      point(contacts[static_cast<size_t>(manifoldPoint_[mk] + k)], r[k]);
      continue;
    }
    ContactDef c;  // deferred: not stored (build), defined here from the manifold's point
    definePoint((*built_)[mk], (*built_)[mk].points[k], worldFrame_, c);
    point(c, r[k]);
  }
  Row* fr = r + count;
  formulateFriction(f, A, B, fr, false);
  if (warm_) {
    carryFrictionImpulse(f.lastImpulse, B, fr);  // last step's, on this step's tangents
    fr[2].lambda = f.lastTwist;
  }
  if (!exempt_)
    for (int k = 0; k < 3; ++k) fr[k].velocityLevel = false;  // the report's rule on every row
  const BodyMass& mA = (*mass_)[static_cast<size_t>(f.a)];
  const BodyMass& mB = (*mass_)[static_cast<size_t>(f.b)];
  for (int k = 0; k < count + 3; ++k) finishRow(r[k], mA, mB, applyScale_);
  coupling = frictionCoupling(fr);
}

namespace {
void prefetchBytes(const void* from, size_t bytes) {
  const char* p = static_cast<const char*>(from);
  for (const char* end = p + bytes; p < end; p += 64) __builtin_prefetch(p);
}
}  // namespace

void ConstraintSet::prefetchManifold(size_t k) const {
  if (!deferred_) {
    const FrictionDef& f = frictions[k];
    prefetchBytes(&rows[static_cast<size_t>(f.firstNormal)], static_cast<size_t>(f.row + 3 - f.firstNormal) * sizeof(Row));
    return;
  }
  prefetchDefinition(k);
}

void ConstraintSet::prefetchDefinition(size_t k) const {
  prefetchBytes(&frictions[k], sizeof(FrictionDef));
  const Manifold& m = (*built_)[k];
  prefetchBytes(m.points, static_cast<size_t>(m.count) * sizeof(ManifoldPoint));
}

size_t ConstraintSet::manifoldBytes() const {
  if (!deferred_) return rows.size() * sizeof(Row);
  const size_t points = manifoldPoint_.empty() ? 0 : static_cast<size_t>(manifoldPoint_.back());
  return frictions.size() * sizeof(FrictionDef) + points * sizeof(ManifoldPoint);
}

uint64_t ConstraintSet::colourKey(int a, int b, const std::vector<BodyMass>& mass) {
  const bool da = mass[static_cast<size_t>(a)].invMass > 0, db = mass[static_cast<size_t>(b)].invMass > 0;
  return uint64_t{static_cast<uint32_t>(a)} << 33 | uint64_t{da} << 32 | uint64_t{static_cast<uint32_t>(b)} << 1 | uint64_t{db};
}

void ConstraintSet::colourManifolds(size_t bodies, bool on) {
  if (!on) {
    colourOrder.clear();
    colourStart.clear();
    lastColourKey_.clear();
    return;
  }
  // The colours are a function of the keys alone (each manifold's bodies and whether each moves):
  // a step whose manifolds are the last one's (a settled scene) keeps them.
  if (!colourStart.empty() && colourKey_ == lastColourKey_) return;
  // Greedy, in the step's order, as Box2D v3's constraint graph assigns them: a manifold between
  // two moving bodies takes the lowest colour below kDynamicColours neither body has yet; one
  // with a static (or sleeping) body, which the solve never moves and which joins every colour,
  // the highest from kColours - 1 down to 1 its moving body has not. The soft step solves them
  // from the highest colour down (docs/algorithms.md, "Colours").
  const size_t nm = colourKey_.size();
  colourUsed_.assign(bodies, 0);
  colourOf_.resize(nm);
  int count[kColours + 1] = {};
  for (size_t k = 0; k < nm; ++k) {
    const uint64_t key = colourKey_[k];
    const size_t a = static_cast<size_t>(key >> 33), b = static_cast<size_t>(key >> 1 & 0x7fffffff);
    const bool da = key >> 32 & 1, db = key & 1;
    const uint64_t taken = (da ? colourUsed_[a] : 0) | (db ? colourUsed_[b] : 0);
    int col = kColours;
    if (da && db) {
      const uint64_t free = ~taken & ((1ull << kDynamicColours) - 1);
      if (free) col = __builtin_ctzll(free);
    } else {
      const uint64_t free = ~taken & ~1ull;
      if (free) col = 63 - __builtin_clzll(free);
    }
    if (col < kColours) {
      if (da) colourUsed_[a] |= 1ull << col;
      if (db) colourUsed_[b] |= 1ull << col;
    }
    colourOf_[k] = static_cast<unsigned char>(col);
    ++count[col];
  }
  colourStart.assign(kColours + 2, 0);
  for (int col = 0; col <= kColours; ++col)
    colourStart[static_cast<size_t>(col) + 1] = colourStart[static_cast<size_t>(col)] + count[col];
  colourOrder.resize(nm);
  int at[kColours + 1];
  std::copy(colourStart.begin(), colourStart.end() - 1, at);
  for (size_t k = 0; k < nm; ++k) colourOrder[static_cast<size_t>(at[colourOf_[k]]++)] = static_cast<int>(k);
  lastColourKey_ = colourKey_;
}

void ConstraintSet::findIslands(bool split) {
  // Only the bodies of manifolds and joints are read, never the rows, which would stream the
  // step's largest array through the cache once more.
  // Islands off: one island, the whole step (island() gives whole()).
  if (!split) {
    islands_.assign(2, Island{});
    lastIslandKey_.clear();
    return;
  }
  // The lists are a function of the key alone: a step whose manifolds have the bodies and point
  // counts of the last (a settled scene) keeps them rather than finding them again, on the
  // calling thread alone (docs/benchmarks.md, "A5's islands kept").
  islandKey_.resize(frictions.size() + 4);
  islandKey_[0] = static_cast<uint64_t>(unitOrder_) | uint64_t{contactBlocks_} << 8 | uint64_t{stableBlocks_} << 9 |
                  uint64_t{colourStart.empty()} << 10;
  islandKey_[1] = reinterpret_cast<uintptr_t>(model_);
  islandKey_[2] = uint64_t{units.size()} << 32 | rows.size();
  islandKey_[3] = uint64_t{joints.size()} << 32 | model_->bodies.size();
  for (size_t k = 0; k < frictions.size(); ++k) {
    const FrictionDef& f = frictions[k];
    islandKey_[k + 4] = uint64_t{static_cast<uint32_t>(f.a)} << 36 | uint64_t{static_cast<uint32_t>(f.b)} << 8 |
                        static_cast<uint64_t>(f.normalCount);
  }
  if (islandKey_ == lastIslandKey_) return;
  islandKey_.swap(lastIslandKey_);
  const std::vector<Body>& bodies = model_->bodies;
  const int nb = static_cast<int>(bodies.size());
  auto dynamic = [&](int i) { return !bodies[static_cast<size_t>(i)].isStatic; };
  auto jointBodies = [&](const JointRef& ref) -> const Joint& { return model_->joints[static_cast<size_t>(ref.joint)]; };
  parent_.resize(static_cast<size_t>(nb));
  for (int i = 0; i < nb; ++i) parent_[static_cast<size_t>(i)] = i;
  auto root = [&](int i) {  // with path halving
    while (parent_[static_cast<size_t>(i)] != i)
      i = parent_[static_cast<size_t>(i)] = parent_[static_cast<size_t>(parent_[static_cast<size_t>(i)])];
    return i;
  };
  auto unite = [&](int a, int b) {
    if (!dynamic(a) || !dynamic(b)) return;
    a = root(a), b = root(b);
    if (a != b) parent_[static_cast<size_t>(std::max(a, b))] = std::min(a, b);  // the lowest body is the root
  };
  for (const FrictionDef& f : frictions) unite(f.a, f.b);
  for (const JointRef& ref : joints) unite(jointBodies(ref).bodyA, jointBodies(ref).bodyB);
  // Islands numbered in order of their lowest body.
  islandOf_.assign(static_cast<size_t>(nb), -1);
  int count = 0;
  for (int i = 0; i < nb; ++i) {
    if (!dynamic(i)) continue;
    int& id = islandOf_[static_cast<size_t>(root(i))];
    if (id < 0) id = count++;
    islandOf_[static_cast<size_t>(i)] = id;
  }
  // One island (a pyramid, or nothing dynamic): the whole step, no lists needed.
  if (count <= 1) {
    islands_.assign(2, Island{});
    return;
  }
  auto of = [&](int a, int b) { return std::max(0, islandOf_[static_cast<size_t>(dynamic(a) ? a : b)]); };
  // Bodies, joints and manifolds by counting sort, which keeps the step's order within an island:
  // islands_[k] is where island k's entries start, islands_[count] the end of all.
  islands_.assign(static_cast<size_t>(count) + 1, Island{});
  for (int i = 0; i < nb; ++i)
    if (dynamic(i)) ++islands_[static_cast<size_t>(islandOf_[static_cast<size_t>(i)]) + 1].bodies;
  for (const JointRef& ref : joints) ++islands_[static_cast<size_t>(of(jointBodies(ref).bodyA, jointBodies(ref).bodyB)) + 1].joints;
  for (const FrictionDef& f : frictions) ++islands_[static_cast<size_t>(of(f.a, f.b)) + 1].manifolds;
  for (size_t k = 1; k < islands_.size(); ++k) {
    islands_[k].bodies += islands_[k - 1].bodies;
    islands_[k].joints += islands_[k - 1].joints;
    islands_[k].manifolds += islands_[k - 1].manifolds;
  }
  cursor_.assign(islands_.begin(), islands_.end());
  islandBodies_.resize(static_cast<size_t>(islands_.back().bodies));
  islandJoints_.resize(joints.size());
  islandManifolds_.resize(frictions.size());
  for (int i = 0; i < nb; ++i)
    if (dynamic(i)) islandBodies_[static_cast<size_t>(cursor_[static_cast<size_t>(islandOf_[static_cast<size_t>(i)])].bodies++)] = i;
  for (int k = 0; k < static_cast<int>(joints.size()); ++k) {
    const Joint& j = jointBodies(joints[static_cast<size_t>(k)]);
    islandJoints_[static_cast<size_t>(cursor_[static_cast<size_t>(of(j.bodyA, j.bodyB))].joints++)] = k;
  }
  for (int k = 0; k < static_cast<int>(frictions.size()); ++k) {
    const FrictionDef& f = frictions[static_cast<size_t>(k)];
    islandManifolds_[static_cast<size_t>(cursor_[static_cast<size_t>(of(f.a, f.b))].manifolds++)] = k;
  }
  // With the contact rows deferred (and no joints) there is no unit or row to list.
  if (deferred_) return;
  // Units and rows island by island, each in the step's order: joints' first, then the
  // manifolds' friction and normal units in the order build() put them; rows are joints' then
  // manifolds' (normal rows, then friction), as build() laid them out.
  islandUnits_.resize(units.size());
  islandRows_.resize(rows.size());
  int nu = 0, nr = 0;
  for (int k = 0; k < count; ++k) {
    Island& is = islands_[static_cast<size_t>(k)];
    const Island& next = islands_[static_cast<size_t>(k) + 1];
    is.units = nu;
    is.rows = nr;
    for (int q = is.joints; q < next.joints; ++q) {
      const JointRef& ref = joints[static_cast<size_t>(islandJoints_[static_cast<size_t>(q)])];
      for (int u = 0; u < ref.units; ++u) islandUnits_[static_cast<size_t>(nu++)] = ref.firstUnit + u;
      for (int r = 0; r < ref.count; ++r) islandRows_[static_cast<size_t>(nr++)] = ref.first + r;
    }
    const IndexRange mine{islandManifolds_.data() + is.manifolds, 0, next.manifolds - is.manifolds};
    forEachContactUnit(
        frictions, mine, unitOrder_,
        [&](const FrictionDef& f) {
          const int n = f.unit >= 0 ? 1 : f.normalCount;
          for (int u = 0; u < n; ++u) islandUnits_[static_cast<size_t>(nu++)] = f.firstNormalUnit + u;
        },
        [&](const FrictionDef& f) { islandUnits_[static_cast<size_t>(nu++)] = f.frictionUnit; });
    for (int q = is.manifolds; q < next.manifolds; ++q) {
      const FrictionDef& f = frictions[static_cast<size_t>(islandManifolds_[static_cast<size_t>(q)])];
      for (int r = f.firstNormal; r < f.row + 3; ++r) islandRows_[static_cast<size_t>(nr++)] = r;
    }
  }
  islands_.back().units = nu;
  islands_.back().rows = nr;
}

ConstraintPart ConstraintSet::islands(int first, int last) const {
  if (islands_.size() == 2) return whole(model_->bodies.size());
  const Island& a = islands_[static_cast<size_t>(first)];
  const Island& b = islands_[static_cast<size_t>(last)];
  return {{islandUnits_.data() + a.units, 0, b.units - a.units},
          {islandRows_.data() + a.rows, 0, b.rows - a.rows},
          {islandBodies_.data() + a.bodies, 0, b.bodies - a.bodies},
          {islandJoints_.data() + a.joints, 0, b.joints - a.joints}};
}

IndexRange ConstraintSet::islandManifolds(int k) const {
  if (islands_.size() == 2) return {nullptr, 0, static_cast<int>(frictions.size())};
  const Island& a = islands_[static_cast<size_t>(k)];
  const Island& b = islands_[static_cast<size_t>(k) + 1];
  return {islandManifolds_.data() + a.manifolds, 0, b.manifolds - a.manifolds};
}

ConstraintPart ConstraintSet::whole(size_t bodies) const {
  return {{nullptr, 0, static_cast<int>(units.size())},
          {nullptr, 0, static_cast<int>(rows.size())},
          {nullptr, 0, static_cast<int>(bodies)},
          {nullptr, 0, static_cast<int>(joints.size())}};
}

void ConstraintSet::reformulateJoints(const IndexRange& list, const std::vector<Pose>& poses,
                                      const std::vector<BodyMass>& mass, double h, double applyScale) {
  for (int k = 0; k < list.count; ++k) {
    const JointRef& ref = joints[static_cast<size_t>(list[k])];
    formulateJoint(ref, poses, h, true);
    finishJoint(ref, mass, applyScale);
  }
}

void ConstraintSet::formulateJoint(const JointRef& ref, const std::vector<Pose>& poses, double h, bool jacobianOnly) {
  const Joint& j = model_->joints[static_cast<size_t>(ref.joint)];
  substep::formulateJoint(j, poses[static_cast<size_t>(j.bodyA)], poses[static_cast<size_t>(j.bodyB)], h,
                          &rows[static_cast<size_t>(ref.first)], jacobianOnly);
}

namespace {

// The inverse of a symmetric positive definite n x n K (n <= 4, a template argument so that
// the loops unroll) by K = L D Lᵀ (L unit lower triangular); false if K is not positive definite
// to working precision (a pivot Dᵢ <= 1e-14 Kᵢᵢ, Cholesky's test on Lᵢᵢ²). No square roots and
// one division per pivot: Cholesky's chain of square roots and divisions was most of a contact
// block's formulation.
template <int n>
bool invertSpd(const double (&K)[4][4], double (&inv)[4][4]) {
  // Not zero-filled: every entry read is written first.
  double L[4][4], D[4], invD[4];
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < i; ++j) {  // L[i][j] Dⱼ = Kᵢⱼ - Σₖ L[i][k] Dₖ L[j][k]
      double s = K[i][j];
      for (int k = 0; k < j; ++k) s -= L[i][k] * D[k] * L[j][k];
      L[i][j] = s * invD[j];
    }
    double d = K[i][i];
    for (int k = 0; k < i; ++k) d -= L[i][k] * D[k] * L[i][k];
    if (!(d > 1e-14 * K[i][i])) return false;
    D[i] = d;
    invD[i] = 1 / d;
  }
  // L⁻¹ (unit lower triangular), then K⁻¹ = L⁻ᵀ D⁻¹ L⁻¹.
  double M[4][4];
  for (int i = 0; i < n; ++i) {
    M[i][i] = 1;
    for (int j = 0; j < i; ++j) {
      double s = 0;
      for (int k = j; k < i; ++k) s -= L[i][k] * M[k][j];
      M[i][j] = s;
    }
  }
  for (int i = 0; i < n; ++i)
    for (int j = 0; j <= i; ++j) {
      double s = 0;
      for (int k = i; k < n; ++k) s += M[k][i] * invD[k] * M[k][j];
      inv[i][j] = inv[j][i] = s;
    }
  return true;
}

// A block unit's K (the block of Γ = J̌ M̌⁻¹ J̌ᵀ, unscaled as the effective mass of single rows)
// and its inverse (contact blocks: of K regularised), the rest of both the identity's.
template <int n>
void formBlock(const Row* b, const double (&unscale)[4], const BodyMass* mass, bool contact, BlockData& d) {
  double K[4][4], inv[4][4];  // the leading n x n of each is written before it is read
  for (int k = 0; k < n; ++k)
    for (int i = 0; i <= k; ++i)  // symmetric
      K[i][k] = K[k][i] = unscale[k] > 0 ? coupling(b[i], b[k]) * unscale[k] : gammaEntry(b[i], b[k], mass);
  // Every entry written once, the unused ones as zero, so nothing is filled twice.
  for (int k = 0; k < 4; ++k)
    for (int i = 0; i < 4; ++i) d.K(i, k) = i < n && k < n ? K[i][k] : 0.0;
  // Four coplanar points make K singular (rank 3): regularise slightly, so the full set's answer
  // is the even, minimum-norm one.
  if (contact)
    for (int i = 0; i < n; ++i) K[i][i] *= 1 + 1e-4;
  const bool ok = invertSpd<n>(K, inv);
  for (int k = 0; k < 4; ++k)
    for (int i = 0; i < 4; ++i) d.invK(i, k) = !ok ? 0.0 : i < n && k < n ? inv[i][k] : i == k ? 1.0 : 0.0;
}

}  // namespace

void ConstraintSet::finishAll(const std::vector<BodyMass>& mass, double applyScale, bool contactsFinished) {
  // Blocks and couplings numbered here, in unit order (finishUnit only fills them); then rows and
  // units on the step's threads. The k-th Friction unit is manifold k's in every unit order.
  int friction = 0;
  for (SolveUnit& u : units) {
    if (u.kind == SolveUnit::Single || u.block >= 0) continue;
    if (u.kind == SolveUnit::Friction) {
      u.block = friction++;
    } else {
      u.block = static_cast<int>(blocks.size());
      blocks.emplace_back();
    }
  }
  assert(friction == 0 || static_cast<size_t>(friction) == couplings.size());
  const size_t finish = contactsFinished ? static_cast<size_t>(contactFirstRow) : rows.size();
  parallel(finish, 512, [&](size_t first, size_t last) {
    finishRows(static_cast<int>(first), static_cast<int>(last), mass, applyScale);
  });
  // Single rows have nothing more, the friction units' couplings were made with their rows.
  if (contactsFinished && blocks.empty()) return;
  parallel(units.size(), 256, [&](size_t first, size_t last) {
    for (size_t u = first; u < last; ++u) {
      const SolveUnit::Kind kind = units[u].kind;
      if (contactsFinished && (kind == SolveUnit::Friction || (kind == SolveUnit::Contact && blocksInLanes_))) continue;
      finishUnit(units[u], mass, applyScale);
    }
  });
}

void ConstraintSet::finishJoint(const JointRef& ref, const std::vector<BodyMass>& mass, double applyScale) {
  finishRows(ref.first, ref.first + ref.count, mass, applyScale);
  for (int u = ref.firstUnit; u < ref.firstUnit + ref.units; ++u) finishUnit(units[static_cast<size_t>(u)], mass, applyScale);
}

void ConstraintSet::refinishJoints(const std::vector<BodyMass>& mass, double applyScale) {
  for (const JointRef& ref : joints) finishJoint(ref, mass, applyScale);
}

void ConstraintSet::finishRows(int firstRow, int lastRow, const std::vector<BodyMass>& mass, double applyScale) {
  for (int i = firstRow; i < lastRow; ++i) {
    Row& r = rows[static_cast<size_t>(i)];
    // A motor is solved exactly under every algorithm: κ does not scale it (docs/algorithms.md),
    // unless the report's literal κ on every row is asked for (motorUnscaled off).
    finishRow(r, mass[static_cast<size_t>(r.a)], mass[static_cast<size_t>(r.b)],
              r.velocityTarget && motorUnscaled_ ? 1.0 : applyScale);
  }
}

void ConstraintSet::finishUnit(SolveUnit& u, const std::vector<BodyMass>& mass, double applyScale) {
  if (u.kind == SolveUnit::Single) return;
  if (u.kind == SolveUnit::Friction) {
    const Row* r = &rows[static_cast<size_t>(u.first)];
    couplings[static_cast<size_t>(u.block)] = frictionCoupling(r);
    return;
  }
  // A block's rows share their two bodies (one joint part, one manifold), so its Γ entries are
  // J̌ᵢ · M̌⁻¹J̌ₖᵀ with the latter already in the rows (scaled by applyScale: undone here).
  BlockData& d = blocks[static_cast<size_t>(u.block)];
  const Row* b = &rows[static_cast<size_t>(u.first)];
  const double unscaleAll = applyScale > 0 ? 1 / applyScale : 0;
  double unscale[4] = {};  // undoes each row's scale of M̌⁻¹J̌ᵀ; 0: from the masses
  for (int k = 0; k < u.size; ++k) unscale[k] = b[k].velocityTarget && motorUnscaled_ ? 1.0 : unscaleAll;
  const bool contact = u.kind == SolveUnit::Contact;
  switch (u.size) {
    case 2: formBlock<2>(b, unscale, mass.data(), contact, d); break;
    case 3: formBlock<3>(b, unscale, mass.data(), contact, d); break;
    default: formBlock<4>(b, unscale, mass.data(), contact, d); break;
  }
}

void ConstraintSet::reformulate(const std::vector<Pose>& poses, const std::vector<BodyMass>& mass, double h,
                                Reformulation what, double applyScale) {
  if (what == Reformulation::JointJacobians) {
    reformulateJoints(IndexRange{nullptr, 0, static_cast<int>(joints.size())}, poses, mass, h, applyScale);
    return;
  }
  for (const JointRef& ref : joints) formulateJoint(ref, poses, h, false);  // β too
  if (what == Reformulation::Everything) {
    frames_.assign(poses.begin(), poses.end());
    for (const ContactDef& c : contacts) {
      Row& r = rows[static_cast<size_t>(c.row)];
      const double hi = r.hi;
      formulateContact(c, frames_[static_cast<size_t>(c.a)], frames_[static_cast<size_t>(c.b)], h, slop_, r, false);
      r.hi = hi;  // a point held inactive (no speculative points) stays so for the step
      r.bias -= r.split;  // the step's split-off position error stays with the position solve
    }
    for (FrictionDef& f : frictions) {
      Row* fr = &rows[static_cast<size_t>(f.row)];
      // The last sub-step's tangential impulse, which the next one starts from when warm starting
      // (proc3:15 re-formulates, the tangents with it): carried as build() carries a step's, or a
      // switch of the tangent basis would re-apply it up to 60 degrees off.
      const Vec3 impulse = frictionImpulseInB(f.qB, fr);
      f.qB = poses[static_cast<size_t>(f.b)].q;
      const bool level = fr[0].velocityLevel;
      formulateFriction(f, frames_[static_cast<size_t>(f.a)], frames_[static_cast<size_t>(f.b)], fr, false);
      for (int k = 0; k < 3; ++k) fr[k].velocityLevel = level;
      carryFrictionImpulse(impulse, frames_[static_cast<size_t>(f.b)], fr);
    }
    finishAll(mass, applyScale, false);
  } else {
    refinishJoints(mass, applyScale);
  }
}

void ConstraintSet::storeImpulses(std::vector<Manifold>& manifolds) {
  for (const JointRef& ref : joints)
    for (int i = 0; i < ref.count; ++i)
      jointLambda_[static_cast<size_t>(jointLambdaFirst_[static_cast<size_t>(ref.joint)] + i)] =
          rows[static_cast<size_t>(ref.first + i)].lambda;
  // Deferred, the stepper left the manifolds' impulses in `impulses`; else they are in the rows. A
  // manifold's normal rows are its first (build() lays them out so): its points' ContactDefs, 192
  // bytes each, are not read for their row (on the 100-level pyramid, 7 MB a step).
  parallel(manifolds.size(), 256, [&](size_t first, size_t last) {
    for (size_t f = first; f < last; ++f) {
      Manifold& m = manifolds[f];
      if (deferred_) {
        const ManifoldImpulses& i = impulses[f];
        for (int p = 0; p < m.count; ++p) m.points[p].lambda = i.normal[p];
        m.frictionImpulse = i.tangentInB;
        m.twistImpulse = i.twist;
        if (blocksInLanes_ && m.count > 1) m.blockMask = laneBlocks_[f].lastMask;  // A5's groups
        continue;
      }
      const Row* normals = &rows[static_cast<size_t>(manifoldRow_[f])];
      for (int p = 0; p < m.count; ++p) m.points[p].lambda = normals[p].lambda;
      const Row* fr = &rows[static_cast<size_t>(frictions[f].row)];
      m.frictionImpulse = frictionImpulseInB(frictions[f].qB, fr);
      m.twistImpulse = fr[2].lambda;
      if (frictions[f].unit >= 0)
        m.blockMask = blocks[static_cast<size_t>(units[static_cast<size_t>(frictions[f].unit)].block)].lastMask;
    }
  });
}

void ConstraintSet::recordApproach(const Vec3* v, const Vec3* w) {
  // Only a bouncing pair reads it (applyRestitution); the others' stays build()'s zero.
  parallel(bouncing.size(), 1024, [&](size_t first, size_t last) {
    for (size_t k = first; k < last; ++k) {
      ContactDef& c = contacts[static_cast<size_t>(bouncing[k])];
      c.approach = rowVelocity(rows[static_cast<size_t>(c.row)], v, w);
    }
  });
}

double ConstraintSet::maxPenetration(const std::vector<Pose>& poses) const {
  double worst = 0;
  eachContact([&](const ContactDef& c) {
    worst = std::max(worst, -contactGap(c, poses[static_cast<size_t>(c.a)], poses[static_cast<size_t>(c.b)]));
  });
  return worst;
}

double ConstraintSet::maxJointError(const std::vector<Pose>& poses) const {
  double worst = 0;
  if (!model_) return 0;
  for (const JointRef& ref : joints) {
    const Joint& j = model_->joints[static_cast<size_t>(ref.joint)];
    const Pose& A = poses[static_cast<size_t>(j.bodyA)];
    const Pose& B = poses[static_cast<size_t>(j.bodyB)];
    worst = std::max(worst, jointError(j, A, B));
  }
  return worst;
}

}  // namespace substep

// build()'s stored contact rows, eight manifolds at a time: each group's definitions gathered lane
// by lane, formulated by the lanes' kernel (soft_lanes.h, Kernel::formulateRows: formulateContact,
// formulateFriction, finishRow, frictionCoupling and formBlock side by side, in their order of
// operations), and copied into the rows, couplings and blocks formulateManifold and finishUnit
// would have written: every number the same to the last bit (tests/test_lanes.cpp). What is not
// arithmetic (bodies, flags) is set here, as formulateManifold sets it. Asked for lane groups
// (askLaneGroups), the groups are the runs of the step's order, or of each part of whole islands,
// and are kept for the sweep.
#include "physics/constraints/constraint_set.h"
#include "physics/step_arrays.h"
#include "physics/steppers/soft_lanes_fill.h"

#include <algorithm>
#include <utility>

namespace substep {

namespace {

// Lane l of group g's row into a stored one, with M̌⁻¹J̌ᵀ as finishRow makes it.
void copyRow(const lanes::RigidGroup& g, const lanes::RigidRowLanes& from, int l, Row& to) {
  resetRowState(to);
  to.a = g.a[l];
  to.b = g.b[l];
  for (int i = 0; i < 3; ++i) {
    to.lin[i] = from.lin[i].x[l];
    to.angA[i] = from.angA[i].x[l];
    to.angB[i] = from.angB[i].x[l];
    to.mAngA[i] = g.scale * (g.invIA[i].x[l] * to.angA[i]);
    to.mAngB[i] = g.scale * (g.invIB[i].x[l] * to.angB[i]);
  }
  to.mA = g.mA.x[l];  // applyScale_ times the bodies' inverse masses
  to.mB = g.mB.x[l];
  to.effMass = from.effMass.x[l];
  to.bias = from.bias.x[l];
  to.lambda = from.lambda.x[l];
}

}  // namespace

lanes::Formulation ConstraintSet::laneFormulation() const {
  lanes::Formulation f = lanes::formulation(*this, h_);
  f.scale = applyScale_;
  f.unscale = 1 / applyScale_;  // finishUnit's unscale of a contact block's rows
  // From the settings, not frictions[0]: every block of build()'s definitions formulates its own
  // manifolds while block 0 may not have written that one yet.
  f.bodiesFrame = !worldFrame_;
  f.blocks = blocksInLanes_;
  f.warm = warm_;
  return f;
}

void ConstraintSet::formulateGroup(const int* manifolds, int count, const lanes::Formulation& f, lanes::ManifoldLanes& in,
                                   lanes::RigidGroup& g) {
  lanes::MassLanes m;
  g.count = count;
  g.normals = 0;
  for (int l = 0; l < lanes::kLanes; ++l) {
    // A lane not in use reads the group's first manifold, with no points: zero rows and masses.
    const size_t k = static_cast<size_t>(manifolds[l < count ? l : 0]);
    const FrictionDef& fd = frictions[k];
    lanes::gatherManifold(*this, k, l, in);
    if (l >= count) in.normals[l] = 0;
    const BodyMass& A = (*mass_)[static_cast<size_t>(fd.a)];
    const BodyMass& B = (*mass_)[static_cast<size_t>(fd.b)];
    m.mA.x[l] = A.invMass;
    m.mB.x[l] = B.invMass;
    for (int i = 0; i < 3; ++i) {
      m.invIA[i].x[l] = A.invI[i];
      m.invIB[i].x[l] = B.invI[i];
    }
    g.manifold[l] = static_cast<int>(k);
    g.a[l] = fd.a;
    g.b[l] = fd.b;
    g.points[l] = in.normals[l];
    g.block[l] = -1;  // numbered by finishAll
    g.normals = std::max(g.normals, in.normals[l]);
  }
  lanes::BlockLanes blocks;
  lanes::kernel().formulateRows(in, m, g, blocks, f);
  for (int l = 0; l < count; ++l) {
    const size_t k = static_cast<size_t>(manifolds[l]);
    const FrictionDef& fd = frictions[k];
    if (!deferred_) {
      for (int q = 0; q < fd.normalCount + 3; ++q) laneRow(g, l, q, rows[static_cast<size_t>(manifoldRow_[k] + q)]);
      couplings[k] = {g.g10.x[l], g.g20.x[l], g.g21.x[l]};
    }
    if (!blocksInLanes_ || fd.normalCount < 2) continue;
    // Deferred, the block's only reader is the lanes' search past the sets they try themselves
    // (searchContactBlock), which reads K and not K⁻¹ (the group holds that).
    BlockData& d = laneBlocks_[k];
    for (int col = 0; col < lanes::kMaxNormals; ++col)
      for (int row = 0; row < lanes::kMaxNormals; ++row) d.K(row, col) = blocks.K[row][col].x[l];
    if (!deferred_)
      for (int col = 0; col < lanes::kMaxNormals; ++col)
        for (int row = 0; row < lanes::kMaxNormals; ++row) d.invK(row, col) = g.invK[row][col].x[l];
  }
}

void ConstraintSet::laneRow(const lanes::RigidGroup& g, int l, int q, Row& row) const {
  const FrictionDef& fd = frictions[static_cast<size_t>(g.manifold[l])];
  if (q < fd.normalCount) {
    copyRow(g, g.normal[q], l, row);
    row.lo = 0;
    row.hi = kInfinity;
    markApart(row, speculative_);
    return;
  }
  const int i = q - fd.normalCount;
  copyRow(g, g.friction[i], l, row);
  row.velocityLevel = exempt_;
  row.lo = -g.mu[i].x[l];
  row.hi = g.mu[i].x[l];
  row.normalRow = fd.firstNormal;
  row.normalCount = fd.normalCount;
}

void ConstraintSet::formulateManifoldsInLanes(size_t first, size_t last) {
  if (first == last) return;
  const lanes::Formulation f = laneFormulation();
  // Not zero-filled: every lane is gathered before the kernel reads it.
  lanes::ManifoldLanes in;
  lanes::RigidGroup g;
  int manifolds[lanes::kLanes];
  for (size_t at = first; at < last; at += lanes::kLanes) {
    const int count = static_cast<int>(std::min<size_t>(lanes::kLanes, last - at));
    for (int l = 0; l < count; ++l) manifolds[l] = static_cast<int>(at) + l;
    formulateGroup(manifolds, count, f, in, g);
  }
}

void ConstraintSet::formulateLaneGroups() {
  // The parts: whole islands in their order, a part closed once the manifolds so far reach its
  // share of them. One part (asked so, or one island): the whole step, in the step's order.
  const int islandsFound = islandCount();
  lanePartIslands_.clear();
  if (laneGroupParts_ > 1 && deferred_ && islands_.size() > 2) {  // deferred: build() found the islands first
    const size_t total = frictions.size(), parts = static_cast<size_t>(laneGroupParts_);
    lanePartIslands_.push_back(0);
    const auto manifoldsBefore = [&](int island) { return static_cast<size_t>(islands_[static_cast<size_t>(island)].manifolds); };
    for (int k = 1; k < islandsFound; ++k) {
      const size_t done = manifoldsBefore(k);  // no part without a manifold, before or after the cut
      if (done * parts >= lanePartIslands_.size() * total && done > manifoldsBefore(lanePartIslands_.back()) && done < total)
        lanePartIslands_.push_back(k);
    }
    lanePartIslands_.push_back(islandsFound);
    if (lanePartIslands_.size() == 2) lanePartIslands_.clear();  // one part: the step's order
  }
  const size_t parts = lanePartIslands_.empty() ? 1 : lanePartIslands_.size() - 1;
  if (laneRuns_.size() < parts) laneRuns_.resize(parts);
  // Part p's manifolds: islandManifolds_ from its first island's to its last's end.
  const auto partList = [&](size_t p) -> std::pair<const int*, size_t> {
    if (lanePartIslands_.empty()) return {nullptr, frictions.size()};
    const Island& a = islands_[static_cast<size_t>(lanePartIslands_[p])];
    const Island& b = islands_[static_cast<size_t>(lanePartIslands_[p + 1])];
    return {islandManifolds_.data() + a.manifolds, static_cast<size_t>(b.manifolds - a.manifolds)};
  };
  parallel(parts, 1, [&](size_t first, size_t last) {
    for (size_t p = first; p < last; ++p) {
      const auto [list, count] = partList(p);
      laneRuns_[p].order(frictions, *mass_, list, count);
    }
  });
  laneOrder_.clear();
  laneGroupStart_.clear();
  laneRunGroups_.clear();
  lanePartGroups_.clear();
  runCount_ = 0;
  for (size_t p = 0; p < parts; ++p) {
    const int* list = partList(p).first;
    const std::vector<int>& start = laneRuns_[p].starts();
    const int base = static_cast<int>(laneOrder_.size());
    for (int at : laneRuns_[p].manifolds()) laneOrder_.push_back(list ? list[at] : at);
    lanePartGroups_.push_back(static_cast<int>(laneGroupStart_.size()));
    for (size_t r = 0; r + 1 < start.size(); ++r) {
      laneRunGroups_.push_back(static_cast<int>(laneGroupStart_.size()));
      for (int at = start[r]; at < start[r + 1]; at += lanes::kLanes) laneGroupStart_.push_back(base + at);
    }
    runCount_ += static_cast<int>(start.size()) - 1;
  }
  laneGroupStart_.push_back(static_cast<int>(laneOrder_.size()));
  laneRunGroups_.push_back(static_cast<int>(laneGroupStart_.size()) - 1);
  lanePartGroups_.push_back(static_cast<int>(laneGroupStart_.size()) - 1);
  const std::vector<int>& order = laneOrder_;
  const size_t groups = laneGroupStart_.size() - 1;
  resizeRewritten(laneGroups_, groups, workers());
  const lanes::Formulation f = laneFormulation();
  // The groups take the manifolds in the runs' order, which no hardware prefetch follows: the
  // next group's definitions and points are asked for while this one is formulated.
  const auto prefetch = [&](size_t gi) {
    for (int at = laneGroupStart_[gi]; at < laneGroupStart_[gi + 1]; ++at)
      prefetchDefinition(static_cast<size_t>(order[static_cast<size_t>(at)]));
  };
  parallel(groups, 8, [&](size_t first, size_t last) {
    lanes::ManifoldLanes in;
    for (size_t gi = first; gi < last; ++gi) {
      if (gi + 1 < last) prefetch(gi + 1);
      const int at = laneGroupStart_[gi];
      // A group ends where its run does: the next group starts there.
      int count = std::min(lanes::kLanes, laneGroupStart_[gi + 1] - at);
      formulateGroup(order.data() + at, count, f, in, laneGroups_[gi]);
    }
  });
}

ConstraintPart ConstraintSet::lanePart(int p) const {
  if (lanePartIslands_.empty()) return whole(model_->bodies.size());
  return islands(lanePartIslands_[static_cast<size_t>(p)], lanePartIslands_[static_cast<size_t>(p) + 1]);
}

}  // namespace substep

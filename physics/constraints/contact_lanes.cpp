// build()'s stored contact rows, eight manifolds at a time: each group's definitions gathered lane
// by lane, formulated by the lanes' kernel (soft_lanes.h, Kernel::formulateRows: formulateContact,
// formulateFriction, finishRow, frictionCoupling and formBlock side by side, in their order of
// operations), and copied into the rows, couplings and blocks formulateManifold and finishUnit
// would have written: every number the same to the last bit (tests/test_lanes.cpp). What is not
// arithmetic (bodies, bounds, flags, the warm-start λ) is set here, as formulateManifold sets it.
#include "physics/constraints/constraint_set.h"
#include "physics/steppers/soft_lanes_fill.h"

#include <algorithm>

namespace substep {

namespace {

// Lane l of a formed row into a stored one, with the bodies' scaled inverse masses (finishRow's).
void copyFormed(const lanes::FormedRow& from, int l, int a, int b, double mA, double mB, Row& to) {
  resetRowState(to);
  to.a = a;
  to.b = b;
  for (int i = 0; i < 3; ++i) {
    to.lin[i] = from.lin[i].x[l];
    to.angA[i] = from.angA[i].x[l];
    to.angB[i] = from.angB[i].x[l];
    to.mAngA[i] = from.mAngA[i].x[l];
    to.mAngB[i] = from.mAngB[i].x[l];
  }
  to.mA = mA;
  to.mB = mB;
  to.effMass = from.effMass.x[l];
}

}  // namespace

void ConstraintSet::formulateManifoldsInLanes(size_t first, size_t last) {
  if (first == last) return;
  const lanes::Kernel& kernel = lanes::kernel();
  lanes::Formulation f = lanes::formulation(*this, h_);
  f.scale = applyScale_;
  f.unscale = 1 / applyScale_;  // finishUnit's unscale of a contact block's rows
  f.bodiesFrame = !frictions[first].worldFrame;
  f.blocks = blocksInLanes_;
  // Not zero-filled: a lane not in use is given the group's first manifold, so that no lane
  // computes on what the stack held.
  lanes::ManifoldLanes in;
  lanes::MassLanes m;
  lanes::FormedManifold out;
  for (size_t g = first; g < last; g += lanes::kLanes) {
    const int count = static_cast<int>(std::min<size_t>(lanes::kLanes, last - g));
    for (int l = 0; l < lanes::kLanes; ++l) {
      const size_t k = g + static_cast<size_t>(l < count ? l : 0);
      const FrictionDef& fd = frictions[k];
      lanes::gatherManifold(*this, k, l, in);
      const BodyMass& A = (*mass_)[static_cast<size_t>(fd.a)];
      const BodyMass& B = (*mass_)[static_cast<size_t>(fd.b)];
      m.mA.x[l] = A.invMass;
      m.mB.x[l] = B.invMass;
      for (int i = 0; i < 3; ++i) {
        m.invIA[i].x[l] = A.invI[i];
        m.invIB[i].x[l] = B.invI[i];
      }
    }
    kernel.formulateRows(in, m, out, f);
    for (int l = 0; l < count; ++l) {
      const size_t k = g + static_cast<size_t>(l);
      const FrictionDef& fd = frictions[k];
      const ContactDef* c = &contacts[static_cast<size_t>(manifoldPoint_[k])];
      Row* r = rows.data() + manifoldRow_[k];
      const double mA = applyScale_ * (*mass_)[static_cast<size_t>(fd.a)].invMass;
      const double mB = applyScale_ * (*mass_)[static_cast<size_t>(fd.b)].invMass;
      for (int q = 0; q < fd.normalCount; ++q) {
        Row& row = r[q];
        copyFormed(out.normal[q], l, fd.a, fd.b, mA, mB, row);
        row.bias = out.bias[q].x[l];
        row.lo = 0;
        row.hi = kInfinity;
        row.lambda = warm_ ? c[q].lastLambda : 0.0;
        row.speculative = row.bias < 0 && speculative_;  // formulateManifold's rule
        if (row.bias < 0 && !speculative_) row.hi = row.lambda = 0;
      }
      Row* fr = r + fd.normalCount;
      for (int i = 0; i < 3; ++i) {
        Row& row = fr[i];
        copyFormed(out.friction[i], l, fd.a, fd.b, mA, mB, row);
        const double mu = i < 2 ? fd.mu : fd.mu * fd.radius;
        row.velocityLevel = exempt_;
        row.bias = 0;
        row.lo = -mu;
        row.hi = mu;
        row.normalRow = fd.firstNormal;
        row.normalCount = fd.normalCount;
        row.lambda = !warm_ ? 0.0 : i < 2 ? out.carried[i].x[l] : fd.lastTwist;
      }
      couplings[k] = {out.g10.x[l], out.g20.x[l], out.g21.x[l]};
      if (!blocksInLanes_ || fd.normalCount < 2) continue;
      BlockData& d = laneBlocks_[k];
      for (int col = 0; col < lanes::kMaxNormals; ++col)
        for (int row = 0; row < lanes::kMaxNormals; ++row) {
          d.K(row, col) = out.K[row][col].x[l];
          d.invK(row, col) = out.invK[row][col].x[l];
        }
    }
  }
}

}  // namespace substep

#include "physics/steppers/stepper.h"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>

namespace substep {

void addExternal(StepContext& c, double dt) { addExternal(c, dt, 0, c.bodies()); }

void addExternal(StepContext& c, double dt, size_t firstBody, size_t lastBody) {
  const Vec3 dv = dt * c.model->gravity;
  const Gyroscopic gyro = c.settings->gyroscopic;
  for (size_t i = firstBody; i < lastBody; ++i) {
    if (c.mass[i].invMass == 0) continue;
    c.v[i] += dv;
    if (gyro != Gyroscopic::None) c.w[i] += gyroscopicChange(c.w[i], c.model->bodies[i].inertia, dt, gyro);
  }
}

Vec3 gyroscopicChange(const Vec3& w, const Vec3& I, double dt, Gyroscopic mode) {
  const Vec3 Iw = I.cwiseProduct(w);
  if (mode == Gyroscopic::Explicit) return -dt * I.cwiseInverse().cwiseProduct(w.cross(Iw));
  if (mode == Gyroscopic::None) return Vec3::Zero();
  // f(ω') = I(ω' − ω) + h ω' × Iω' = 0; one Newton step from ω' = ω:
  //   J = I + h ([ω]× I − [Iω]×),   ω' = ω − J⁻¹ h (ω × Iω)
  auto skew = [](const Vec3& a) {
    Mat3 m;
    m << 0, -a.z(), a.y(), a.z(), 0, -a.x(), -a.y(), a.x(), 0;
    return m;
  };
  const Mat3 J = Mat3(I.asDiagonal()) + dt * (skew(w) * I.asDiagonal() - skew(Iw));
  return -J.partialPivLu().solve(dt * w.cross(Iw));
}

void applyRowImpulses(ConstraintSet& cs, std::vector<Vec3>& v, std::vector<Vec3>& w) {
  applyRowImpulses(cs, IndexRange{nullptr, 0, static_cast<int>(cs.rows.size())}, v, w);
}

void applyRowImpulses(ConstraintSet& cs, const IndexRange& rows, std::vector<Vec3>& v, std::vector<Vec3>& w) {
  // Consecutive rows on the same two bodies (a manifold's, a joint's) are applied to those bodies'
  // velocities held here, read once and written back once: the same sums as row by row.
  const Row* held = nullptr;  // the first row applied on the bodies held
  Vec3 vA, wA, vB, wB;
  forEach(rows, [&](size_t q) {
    const Row& r = cs.rows[q];
    if (r.lambda == 0) return;
    if (!held || r.a != held->a || r.b != held->b) {
      if (held) storeMoving(*held, vA, wA, vB, wB, v.data(), w.data());
      held = &r;
      vA = v[static_cast<size_t>(r.a)], wA = w[static_cast<size_t>(r.a)];
      vB = v[static_cast<size_t>(r.b)], wB = w[static_cast<size_t>(r.b)];
    }
    applyImpulse(r, r.lambda, vA, wA, vB, wB);
  });
  if (held) storeMoving(*held, vA, wA, vB, wB, v.data(), w.data());
}

namespace {

// Solves A x = r in place (x holds r on entry) for n <= 4 by Cholesky; false if A is not
// positive definite to working precision (a singular subset of coplanar points). Fixed-size
// loops: the block is at most 4x4 and solved every sweep (docs/benchmarks.md).
bool solveSmall(double (&A)[4][4], double (&x)[4], int n) {
  double L[4][4];
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j <= i; ++j) {
      double sum = A[i][j];
      for (int k = 0; k < j; ++k) sum -= L[i][k] * L[j][k];
      if (i == j) {
        if (!(sum > 1e-12 * A[i][i])) return false;
        L[i][i] = std::sqrt(sum);
      } else {
        L[i][j] = sum / L[j][j];
      }
    }
  }
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < i; ++k) x[i] -= L[i][k] * x[k];
    x[i] /= L[i][i];
  }
  for (int i = n - 1; i >= 0; --i) {
    for (int k = i + 1; k < n; ++k) x[i] -= L[k][i] * x[k];
    x[i] /= L[i][i];
  }
  return true;
}

// A contact block: the normal rows of one manifold, λ >= 0 each. Finds the increment Δ with
//   λ + Δ >= 0,  w = KΔ - b >= 0,  (λ + Δ)ᵢ wᵢ = 0     (b = cBias β - cVel J̌v̌)
// trying none pushing (nothing needs to), every point pushing (the precomputed inverse), then the
// active set that fitted last time (it rarely changes from one sweep to the next), then every
// smaller set by size (searchBlock).
// k is the block's size, a template argument so that the common paths unroll.
template <int k>
void searchBlock(BlockData& d, const double* lam, const double* b, double* delta);

template <int k>
void solveContactBlock(BlockData& d, const double* lam, const double* b, double* delta) {
  bool idle = true;
  for (int i = 0; i < k; ++i) idle = idle && lam[i] == 0 && b[i] <= 0;
  // Nothing pushes and nothing wants to: the empty set fits (w = -b >= 0, Δ = 0). A third of the
  // blocks on a standing pyramid (points apart, or lifted corners); enumerating the sets by size
  // found it last.
  if (idle) {
    for (int i = 0; i < k; ++i) delta[i] = 0;
    return;
  }
  double full[4];
  for (int i = 0; i < k; ++i) {
    full[i] = 0;
    for (int j = 0; j < k; ++j) full[i] += d.invK(i, j) * b[j];
  }
  bool ok = true;
  for (int i = 0; i < k; ++i) ok = ok && lam[i] + full[i] >= 0;
  if (ok) {
    for (int i = 0; i < k; ++i) delta[i] = full[i];
    return;
  }
  searchBlock<k>(d, lam, b, delta);
}

// The sets neither empty nor full: the last that fitted, then the others by size. Reads K and the
// last set, not K⁻¹.
template <int k>
void searchBlock(BlockData& d, const double* lam, const double* b, double* delta) {
  // Rows outside the active set S drop to λ = 0 (Δ = -λ) and must not pull; rows in S solve
  // their block exactly and must stay >= 0.
  auto fits = [&](int mask) {
    int S[4], N[4], ns = 0, nn = 0;
    for (int i = 0; i < k; ++i) (mask >> i & 1 ? S[ns++] : N[nn++]) = i;
    double D[4];
    for (int i = 0; i < nn; ++i) D[N[i]] = -lam[N[i]];
    if (ns > 0) {
      double A[4][4], x[4];
      for (int i = 0; i < ns; ++i) {
        x[i] = b[S[i]];
        for (int j = 0; j < nn; ++j) x[i] -= d.K(S[i], N[j]) * D[N[j]];
        for (int j = 0; j < ns; ++j) A[i][j] = d.K(S[i], S[j]);
      }
      if (!solveSmall(A, x, ns)) return false;
      for (int i = 0; i < ns; ++i) {
        D[S[i]] = x[i];
        if (!std::isfinite(x[i]) || lam[S[i]] + x[i] < 0) return false;
      }
    }
    for (int i = 0; i < nn; ++i) {
      double wi = -b[N[i]];
      for (int j = 0; j < k; ++j) wi += d.K(N[i], j) * D[j];
      if (wi < -1e-12 * (1 + std::abs(b[N[i]]))) return false;
    }
    for (int i = 0; i < k; ++i) delta[i] = D[i];
    return true;
  };
  const int fullMask = (1 << k) - 1;
  if (d.lastMask >= 0 && d.lastMask < fullMask && fits(d.lastMask)) return;
  // The proper subsets of {0..3} by decreasing size (a table: popcount is a library call here).
  static constexpr int kSubsets[15] = {14, 13, 11, 7, 12, 10, 9, 6, 5, 3, 8, 4, 2, 1, 0};
  for (const int mask : kSubsets) {
    if ((mask & fullMask) != mask || mask == fullMask || mask == d.lastMask) continue;
    if (fits(mask)) {
      d.lastMask = mask;
      return;
    }
  }
  for (int i = 0; i < k; ++i) delta[i] = 0;  // no set fits (round-off at a degenerate point): keep λ
}

// The factors of a row's update Δλ = m_eff (cBias β - cVel J̌v̌) (SweepScales).
inline double biasFactor(const Row& r, const SweepScales& k) {
  return r.velocityTarget ? k.biasTarget : (r.speculative && r.bias < 0 ? k.biasSpeculative : k.bias);
}
inline double velFactor(const Row& r, const SweepScales& k) { return r.velocityTarget ? k.velTarget : k.vel; }

// A block unit of N rows on two bodies (velocities va.. read by the caller): b = cBias β - cVel J̌v̌
// for each row, Δλ = K⁻¹ b (stable) or the block's MLCP (contact), applied row by row.
// Inlined in sweepUnits' loop and in UnitLevels' alike (called from two loops, GCC inlines it in
// neither).
template <int N, bool Measure>
__attribute__((always_inline)) inline void solveBlockUnit(ConstraintSet& cs, const SolveUnit& u, Row* r,
                                                          const SweepScales& k, Vec3& va, Vec3& wa, Vec3& vb, Vec3& wb,
                                                          double& change) {
  double b[N], dl[N];
  for (int i = 0; i < N; ++i) b[i] = biasFactor(r[i], k) * r[i].bias - velFactor(r[i], k) * rowVelocity(r[i], va, wa, vb, wb);
  BlockData& d = cs.blocks[static_cast<size_t>(u.block)];
  if (u.kind == SolveUnit::Stable) {
    for (int i = 0; i < N; ++i) {
      dl[i] = 0;
      for (int j = 0; j < N; ++j) dl[i] += d.invK(i, j) * b[j];
    }
  } else {
    double lam[N];
    for (int i = 0; i < N; ++i) lam[i] = r[i].lambda;
    solveContactBlock<N>(d, lam, b, dl);
  }
  for (int i = 0; i < N; ++i) {
    if (dl[i] == 0) continue;
    r[i].lambda += dl[i];
    r[i].pushed = r[i].pushed || r[i].lambda > 0;
    applyImpulse(r[i], dl[i], va, wa, vb, wb);
    if (Measure) noteChange(change, dl[i], r[i].effMass);
  }
}

}  // namespace

void searchContactBlock(BlockData& d, int points, const double* lambda, const double* b, double* delta) {
  switch (points) {
    case 2: searchBlock<2>(d, lambda, b, delta); break;
    case 3: searchBlock<3>(d, lambda, b, delta); break;
    default: searchBlock<4>(d, lambda, b, delta); break;
  }
}

SweepScales SweepScales::havok(const SolverSettings& s) {
  const double bt = s.motorUnscaled ? 1 : s.tau, vt = s.motorUnscaled ? 1 : s.kappa;
  return {s.tau, s.kappa, bt, vt, 1};
}

namespace {

// One solve unit of a sweep (sweep's comment).
template <bool Measure>
__attribute__((always_inline)) inline void solveUnit(ConstraintSet& cs, const SolveUnit& u, Row* rows, Vec3* v, Vec3* w, const SweepScales& k,
                      double& change) {
  if (u.kind == SolveUnit::Single) {
    Row& r = rows[u.first];
    const double target = biasFactor(r, k) * r.bias, cv = velFactor(r, k);
    change = std::max(change, solveRow<Measure>(r, rows, v, w, [&](double jv) { return r.effMass * (target - cv * jv); }));
    return;
  }
  // A unit's rows share their two bodies (one manifold, one joint part): their velocities are
  // read once and written once.
  const int ia = rows[u.first].a, ib = rows[u.first].b;
  Vec3 va = v[ia], wa = w[ia], vb = v[ib], wb = w[ib];
  if (u.kind == SolveUnit::Friction) {  // friction rows are never speculative nor motors
    solveFrictionUnit<Measure>(cs.couplings[static_cast<size_t>(u.block)], &rows[u.first], rows, va, wa, vb, wb, k.bias, k.vel,
                               change);
    storeMoving(rows[u.first], va, wa, vb, wb, v, w);
    return;
  }
  // Blocks: a joint's stable part (2 or 3 rows) or a manifold's normal rows (2 to 4).
  Row* r = &rows[u.first];
  switch (u.size) {
    case 2: solveBlockUnit<2, Measure>(cs, u, r, k, va, wa, vb, wb, change); break;
    case 3: solveBlockUnit<3, Measure>(cs, u, r, k, va, wa, vb, wb, change); break;
    default: solveBlockUnit<4, Measure>(cs, u, r, k, va, wa, vb, wb, change); break;
  }
  storeMoving(*r, va, wa, vb, wb, v, w);
}

// One loop for both forms of sweep, so that the block solves stay inlined in it
// (docs/benchmarks.md); one copy measuring the change, one not.
template <bool Measure>
double sweepUnits(ConstraintSet& cs, const IndexRange& units, std::vector<Vec3>& v, std::vector<Vec3>& w,
                  const SweepScales& k) {
  double change = 0;
  for (int i = 0; i < units.count; ++i)
    solveUnit<Measure>(cs, cs.units[static_cast<size_t>(units[i])], cs.rows.data(), v.data(), w.data(), k, change);
  return change;
}

}  // namespace

bool UnitLevels::build(const ConstraintSet& cs, const ConstraintPart& part, size_t bodies) {
  order_.clear();
  if (part.joints.count > 0) return false;
  const IndexRange& units = part.units;
  const size_t count = static_cast<size_t>(units.count);
  last_.assign(bodies, -1);  // each body's last unit so far (an index into `units`)
  level_.resize(count);
  before_.resize(2 * count);  // by index into `units` first, then by place
  int levels = 0;
  // Each unit's first row is a cache line of its own, far from the last one's: asked for ahead
  // (without, half of this loop's time on the 100-level pyramid went on waiting for them).
  constexpr int kAhead = 16;
  for (int i = 0; i < units.count; ++i) {
    if (i + kAhead < units.count)
      __builtin_prefetch(&cs.rows[static_cast<size_t>(cs.units[static_cast<size_t>(units[i + kAhead])].first)].mA);
    const Row& r = cs.rows[static_cast<size_t>(cs.units[static_cast<size_t>(units[i])].first)];
    const bool movesA = r.mA != 0, movesB = r.mB != 0;  // storeMoving's test
    if (!movesA && !movesB) return false;
    const int prevA = movesA ? last_[static_cast<size_t>(r.a)] : -1;
    const int prevB = movesB ? last_[static_cast<size_t>(r.b)] : -1;
    int level = 0;
    if (prevA >= 0) level = level_[static_cast<size_t>(prevA)] + 1;
    if (prevB >= 0) level = std::max(level, level_[static_cast<size_t>(prevB)] + 1);
    if (movesA) last_[static_cast<size_t>(r.a)] = i;
    if (movesB) last_[static_cast<size_t>(r.b)] = i;
    level_[static_cast<size_t>(i)] = level;
    before_[2 * static_cast<size_t>(i)] = prevA;
    before_[2 * static_cast<size_t>(i) + 1] = prevB == prevA ? -1 : prevB;
    levels = std::max(levels, level + 1);
  }
  // A counting sort by level, stable: each level keeps the part's order.
  std::vector<int>& at = last_;  // reused: each level's next place
  at.assign(static_cast<size_t>(levels) + 1, 0);
  for (const int l : level_) ++at[static_cast<size_t>(l) + 1];
  for (size_t l = 1; l < at.size(); ++l) at[l] += at[l - 1];
  order_.resize(count);
  place_.resize(count);
  for (size_t i = 0; i < count; ++i) {
    const int p = at[static_cast<size_t>(level_[i])]++;
    order_[static_cast<size_t>(p)] = units[static_cast<int>(i)];
    place_[i] = p;
  }
  // The predecessors by place, in place order.
  std::vector<int>& byIndex = level_;  // reused: no longer needed
  byIndex.assign(before_.begin(), before_.end());
  for (size_t i = 0; i < count; ++i)
    for (size_t s = 0; s < 2; ++s) {
      const int q = byIndex[2 * i + s];
      before_[2 * static_cast<size_t>(place_[i]) + s] = q < 0 ? -1 : place_[static_cast<size_t>(q)];
    }
  // The marks: of earlier sweeps (this step's or an earlier one's) they hold a smaller epoch_.
  const size_t chunks = (count + kChunk - 1) / kChunk;
  if (done_.size() < chunks || epoch_ > UINT32_MAX - 64) {
    done_ = std::vector<Done>(std::max(chunks, done_.size()));  // zeroed
    epoch_ = 0;
  }
  return true;
}

template <bool Measure>
void UnitLevels::sweepChunks(ConstraintSet& cs, std::vector<Vec3>& v, std::vector<Vec3>& w, const SweepScales& k,
                             double& change) {
  // The units are not in their rows' order, which the hardware prefetch would follow: the rows
  // and block of the unit kAhead on are asked for while this one is solved (without, s3 of the
  // 100-level pyramid took 40 % longer on one thread in this order).
  constexpr size_t kAhead = 3;
  const size_t count = order_.size();
  const auto solved = [&](size_t p) { return done_[p / kChunk].sweep[p % kChunk].load(std::memory_order_acquire) == epoch_; };
  for (;;) {
    const size_t first = next_.fetch_add(kChunk, std::memory_order_relaxed);
    if (first >= count) return;
    const size_t last = std::min(count, first + kChunk);
    for (size_t p = first; p < last; ++p) {
      if (p + kAhead < count) {
        const SolveUnit& ahead = cs.units[static_cast<size_t>(order_[p + kAhead])];
        const char* row = reinterpret_cast<const char*>(&cs.rows[static_cast<size_t>(ahead.first)]);
        for (const char* end = row + ahead.size * sizeof(Row); row < end; row += 64) __builtin_prefetch(row);
        if (ahead.kind == SolveUnit::Contact) __builtin_prefetch(&cs.blocks[static_cast<size_t>(ahead.block)]);
      }
      // A predecessor in this chunk was solved here, above; one before it, by whichever thread.
      for (size_t s = 0; s < 2; ++s) {
        const int q = before_[2 * p + s];
        if (q >= 0 && static_cast<size_t>(q) < first) spinUntil([&] { return solved(static_cast<size_t>(q)); }, kSweepWaitSpins);
      }
      solveUnit<Measure>(cs, cs.units[static_cast<size_t>(order_[p])], cs.rows.data(), v.data(), w.data(), k, change);
      done_[p / kChunk].sweep[p % kChunk].store(epoch_, std::memory_order_release);
    }
  }
}

double UnitLevels::sweep(ConstraintSet& cs, std::vector<Vec3>& v, std::vector<Vec3>& w, const SweepScales& k,
                         bool measure, WorkerPool& pool) {
  ++epoch_;
  next_.store(0, std::memory_order_relaxed);
  change_.reset(pool.threads());
  // One block a thread; each claims chunks until none is left (a thread that joins late finds
  // fewer, or none: then the others have solved them).
  pool.forBlocks(static_cast<size_t>(pool.threads()), [&](size_t, int thread) {
    double& change = change_.of(thread);
    if (measure) sweepChunks<true>(cs, v, w, k, change);
    else sweepChunks<false>(cs, v, w, k, change);
  });
  return change_.largest();
}

double sweep(ConstraintSet& cs, std::vector<Vec3>& v, std::vector<Vec3>& w, const SweepScales& k, bool measure) {
  return sweep(cs, IndexRange{nullptr, 0, static_cast<int>(cs.units.size())}, v, w, k, measure);
}

double sweep(ConstraintSet& cs, const IndexRange& units, std::vector<Vec3>& v, std::vector<Vec3>& w,
             const SweepScales& k, bool measure) {
  return measure ? sweepUnits<true>(cs, units, v, w, k) : sweepUnits<false>(cs, units, v, w, k);
}

void recordSubStep(StepContext& c, int j) {
  const size_t nb = c.bodies();
  std::copy(c.v.begin(), c.v.end(), c.subV.begin() + static_cast<long>(static_cast<size_t>(j) * nb));
  std::copy(c.w.begin(), c.w.end(), c.subW.begin() + static_cast<long>(static_cast<size_t>(j) * nb));
}

void beginSubSteps(StepContext& c) {
  sizeSubSteps(c);
  beginSubSteps(c, 0, c.bodies());
}

void sizeSubSteps(StepContext& c) {
  const size_t nb = c.bodies();
  c.subPoses.resize(nb);
  c.sumV.resize(nb);
  c.sumW.resize(nb);
  // Sized here, for every body, so that parts of the step (islands on threads) each fill their own.
  c.startV.resize(nb);
  c.startW.resize(nb);
  c.impV.resize(nb);
  c.impW.resize(nb);
}

void beginSubSteps(StepContext& c, size_t first, size_t last) {
  for (size_t i = first; i < last; ++i) {
    c.subPoses[i] = c.poses[i];
    c.sumV[i] = Vec3::Zero();
    c.sumW[i] = Vec3::Zero();
  }
}

void advanceSubPoses(StepContext& c, int j, RotationRule rule) {
  advanceSubPoses(c, j, rule, IndexRange{nullptr, 0, static_cast<int>(c.bodies())});
}

void advanceSubPoses(StepContext& c, int j, RotationRule rule, const IndexRange& bodies) {
  const double dt = c.h() / c.n();
  const size_t nb = c.bodies();
  forEach(bodies, [&](size_t i) {
    if (c.model->bodies[i].isStatic) return;
    const Vec3& v = c.subV[static_cast<size_t>(j) * nb + i];
    const Vec3& w = c.subW[static_cast<size_t>(j) * nb + i];
    c.sumV[i] += dt * v;
    c.subPoses[i].p = c.poses[i].p + c.sumV[i];
    if (rule == RotationRule::Product) {
      c.subPoses[i].q = (c.subPoses[i].q * Rq(dt * w)).normalized();
    } else {
      c.sumW[i] += dt * w;
      c.subPoses[i].q = (c.poses[i].q * Rq(c.sumW[i])).normalized();
    }
  });
}

void startSubStepImpulses(StepContext& c, int j) { startSubStepImpulses(c, j, c.constraints->whole(c.bodies())); }

void startSubStepImpulses(StepContext& c, int j, const ConstraintPart& part) {
  ConstraintSet& cs = *c.constraints;
  if (!c.settings->warmStart) {
    if (j > 0)
      for (int k = 0; k < part.rows.count; ++k) cs.rows[static_cast<size_t>(part.rows[k])].lambda = 0;
    return;
  }
  if (!c.rowsHeld) {
    applyRowImpulses(cs, part.rows, c.v, c.w);
    return;
  }
  forEach(part.bodies, [&](size_t i) {
    c.startV[i] = c.v[i];
    c.startW[i] = c.w[i];
  });
  if (j == 0) {  // last step's λ on this step's J̌
    applyRowImpulses(cs, part.rows, c.v, c.w);
    return;
  }
  forEach(part.bodies, [&](size_t i) {
    c.v[i] += c.impV[i];
    c.w[i] += c.impW[i];
  });
}

void endSubStepImpulses(StepContext& c) { endSubStepImpulses(c, c.constraints->whole(c.bodies())); }

void endSubStepImpulses(StepContext& c, const ConstraintPart& part) {
  if (!c.rowsHeld || !c.settings->warmStart) return;
  forEach(part.bodies, [&](size_t i) {
    c.impV[i] = c.v[i] - c.startV[i];
    c.impW[i] = c.w[i] - c.startW[i];
  });
}

void updateBiases(ConstraintSet& cs, const std::vector<Vec3>& v, const std::vector<Vec3>& w) {
  for (Row& r : cs.rows)
    if (!r.velocityLevel) r.bias -= rowVelocity(r, v.data(), w.data());
}

void stepVelocitiesScaled(StepContext& c, const std::function<void(int j)>& between) {
  ConstraintSet& cs = *c.constraints;
  const int n = c.n(), m = c.settings->iterations;
  const double dt = c.h() / n;
  const SweepScales scales = SweepScales::havok(*c.settings);
  c.stats = StepStats{};
  c.stats.rows = static_cast<int>(cs.rows.size());
  splitPositionErrors(c);
  beginSubSteps(c);
  for (int j = 0; j < n; ++j) {
    addExternal(c, dt);
    startSubStepImpulses(c, j);
    for (int i = 0; i < m && !cs.rows.empty(); ++i) {
      const bool last = j + 1 == n && i + 1 == m;  // the step reports its last sweep's residual
      const double change = sweep(cs, c.v, c.w, scales, last);
      if (last) c.stats.residual = change;
    }
    endSubStepImpulses(c);
    recordSubStep(c, j);
    if (j + 1 < n) between(j);
  }
  c.stats.iterations = n * m;
  const size_t last = static_cast<size_t>(n - 1) * c.bodies();
  applyRestitution(c, &c.subV[last], &c.subW[last], 1.0);
  solvePositionErrors(c, n * m, 1.0);
}

void applyRestitution(StepContext& c, const Vec3* v, const Vec3* w, double applyScale) {
  c.bounced = false;
  if (!c.settings->restitution) return;
  ConstraintSet& cs = *c.constraints;
  const double threshold = c.settings->restitutionThreshold;
  for (const int k : cs.bouncing) {
    const ContactDef& contact = cs.contacts[static_cast<size_t>(k)];
    Row& r = cs.rows[static_cast<size_t>(contact.row)];
    if (contact.approach > -threshold || !r.pushed) continue;
    if (!c.bounced) {
      c.endV.assign(v, v + c.bodies());
      c.endW.assign(w, w + c.bodies());
      c.bounced = true;
    }
    const double target = -contact.restitution * contact.approach;  // separating at e times the approach
    const double next = std::max(0.0, r.lambda + r.effMass * (target - rowVelocity(r, c.endV.data(), c.endW.data())));
    const double dl = next - r.lambda;
    r.lambda = next;
    if (dl != 0) applyImpulse(r, dl / applyScale, c.endV.data(), c.endW.data());
  }
}

void splitPositionErrors(StepContext& c) {
  const size_t nb = c.bodies();
  c.pseudoV.assign(nb, Vec3::Zero());
  c.pseudoW.assign(nb, Vec3::Zero());
  if (!c.settings->splitImpulse) return;
  ConstraintSet& cs = *c.constraints;
  for (const ContactDef& contact : cs.contacts) {
    Row& r = cs.rows[static_cast<size_t>(contact.row)];
    r.split = splitOff(r.bias);
  }
}

void solvePositionErrors(StepContext& c, int sweeps, double applyScale) {
  if (!c.settings->splitImpulse) return;
  ConstraintSet& cs = *c.constraints;
  bool any = false;
  for (const ContactDef& contact : cs.contacts) any |= cs.rows[static_cast<size_t>(contact.row)].split > 0;
  if (!any) return;
  const double target = c.settings->tau / c.n();  // τ of the error, over the whole step
  c.pseudoLambda.assign(cs.contacts.size(), 0.0);
  for (int it = 0; it < sweeps; ++it) {
    for (size_t k = 0; k < cs.contacts.size(); ++k) {
      const Row& r = cs.rows[static_cast<size_t>(cs.contacts[k].row)];
      double dl = r.effMass * (target * r.split - rowVelocity(r, c.pseudoV.data(), c.pseudoW.data()));
      const double next = std::max(0.0, c.pseudoLambda[k] + dl);
      dl = next - c.pseudoLambda[k];
      c.pseudoLambda[k] = next;
      if (dl != 0) applyImpulse(r, dl / applyScale, c.pseudoV.data(), c.pseudoW.data());
    }
  }
}

Quat stepRotation(const Quat& q, const Vec3* w, size_t stride, int n, double dt, RotationRule rule) {
  if (rule == RotationRule::Product) {
    Quat r = q;
    for (int k = 0; k < n; ++k) r = r * Rq(dt * w[static_cast<size_t>(k) * stride]);
    return r.normalized();
  }
  Vec3 sum = Vec3::Zero();
  for (int k = 0; k < n; ++k) sum += dt * w[static_cast<size_t>(k) * stride];
  return (q * Rq(sum)).normalized();
}

namespace {
// f(i) for every body that moves, blocks of bodies on the step's threads: s4 steps each body's
// coordinates from its own velocities alone.
template <class F>
void eachMovingBody(StepContext& c, F f) {
  eachBodyBlock(c, [&](size_t first, size_t last) {
    for (size_t i = first; i < last; ++i)
      if (!c.model->bodies[i].isStatic) f(i);
  });
}
}  // namespace

void stepCoordinatesEssential(StepContext& c) {
  const double h = c.h();
  eachMovingBody(c, [&](size_t i) {
    BodyState& b = c.state->bodies[i];
    b.x += h * (c.v[i] + c.pseudoV[i]);
    const Vec3 omegaWorld = b.q * (c.w[i] + c.pseudoW[i]);
    b.q = (Rq(h * omegaWorld) * b.q).normalized();
    b.v = endVelocity(c, i, c.v[i]);
    b.w = endAngularVelocity(c, i, c.w[i]);
  });
}

void stepCoordinatesSubStepped(StepContext& c, RotationRule rule) {
  const int n = c.n();
  const double dt = c.h() / n;
  const size_t nb = c.bodies();
  eachMovingBody(c, [&](size_t i) {
    BodyState& b = c.state->bodies[i];
    Vec3 sum = Vec3::Zero();
    for (int k = 0; k < n; ++k) sum += dt * c.subV[static_cast<size_t>(k) * nb + i];
    b.x += sum + c.h() * c.pseudoV[i];
    b.q = stepRotation(b.q, &c.subW[i], nb, n, dt, rule);
    if (!c.pseudoW[i].isZero()) b.q = (b.q * Rq(c.h() * c.pseudoW[i])).normalized();
    b.v = endVelocity(c, i, c.subV[static_cast<size_t>(n - 1) * nb + i]);
    b.w = endAngularVelocity(c, i, c.subW[static_cast<size_t>(n - 1) * nb + i]);
  });
}

}  // namespace substep

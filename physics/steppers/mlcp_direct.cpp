#include "physics/steppers/mlcp_direct.h"

#include "physics/steppers/lemke.h"

#include <dart/external/odelcpsolver/lcp.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace substep {

namespace ode = dart::external::ode;

namespace {

// Σλ of the normal rows that bound friction row i.
double normalSum(const DenseMLCP& p, const std::vector<double>& x, int i) {
  double s = 0;
  for (int k = 0; k < p.fcount[static_cast<size_t>(i)]; ++k) s += x[static_cast<size_t>(p.findex[static_cast<size_t>(i)] + k)];
  return std::max(0.0, s);
}

// Bounds of row i given the current λ (friction rows scale by their normals' Σλ).
void bounds(const DenseMLCP& p, const std::vector<double>& x, int i, double& lo, double& hi) {
  lo = p.lo[static_cast<size_t>(i)];
  hi = p.hi[static_cast<size_t>(i)];
  if (p.findex[static_cast<size_t>(i)] >= 0) {
    hi = std::abs(hi) * normalSum(p, x, i);
    lo = -hi;
  }
}

// One Dantzig solve with the friction bounds fixed at ±μ Σ of `normals`' λ. ODE's own friction
// index takes one normal per friction row, and a manifold's friction is bounded by several.
// The work A1 may do in one step, in floating-point operations estimated from the sizes:
// a dense factorisation of n rows is about n³/3, a complete orthogonal decomposition 4n³/3, a
// Lemke pivot 2nz² for nz variables, a Gauss-Seidel sweep n². Each stage asks before it starts.
struct Budget {
  double left;
  bool afford(double flops) const { return flops <= left; }
  void spend(double flops) { left -= flops; }
};

bool dantzig(const DenseMLCP& p, double cfm, const std::vector<double>& normals, std::vector<double>& x) {
  const int n = p.n;
  const int stride = dPAD(n);
  std::vector<double> A(static_cast<size_t>(n) * static_cast<size_t>(stride), 0.0);
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < n; ++k)
      A[static_cast<size_t>(i * stride + k)] = p.A[static_cast<size_t>(i * n + k)];
  for (int i = 0; i < n; ++i) {
    double& d = A[static_cast<size_t>(i * stride + i)];
    d += cfm * std::max(d, 1e-30);
  }
  std::vector<double> b = p.b, w(static_cast<size_t>(n), 0.0), lo(static_cast<size_t>(n)), hi(static_cast<size_t>(n));
  std::vector<int> findex(static_cast<size_t>(n), -1);
  for (int i = 0; i < n; ++i) {
    const size_t s = static_cast<size_t>(i);
    if (p.findex[s] >= 0) {
      hi[s] = std::abs(p.hi[s]) * normalSum(p, normals, i);
      lo[s] = -hi[s];
    } else {
      lo[s] = std::isinf(p.lo[s]) ? -dInfinity : p.lo[s];
      hi[s] = std::isinf(p.hi[s]) ? dInfinity : p.hi[s];
    }
  }
  x.assign(static_cast<size_t>(n), 0.0);
  const bool ok = ode::dSolveLCP(n, A.data(), x.data(), b.data(), w.data(), 0, lo.data(), hi.data(), findex.data(), false);
  for (double v : x)
    if (!std::isfinite(v)) return false;
  return ok;
}

}  // namespace

void assembleMLCP(const std::vector<Row>& rows, const std::vector<BodyMass>& mass, const Vec3* v, const Vec3* w,
                  DenseMLCP& p) {
  const int n = static_cast<int>(rows.size());
  const size_t N = static_cast<size_t>(n);
  p.n = n;
  p.A.assign(N * N, 0.0);
  p.b.resize(N);
  p.lo.resize(N);
  p.hi.resize(N);
  p.findex.resize(N);
  p.fcount.resize(N);
  // Rows touching each body, so Γ is filled only where rows share a body.
  std::vector<std::vector<int>> rowsOf(mass.size());
  for (int i = 0; i < n; ++i) {
    const Row& r = rows[static_cast<size_t>(i)];
    rowsOf[static_cast<size_t>(r.a)].push_back(i);
    if (r.b != r.a) rowsOf[static_cast<size_t>(r.b)].push_back(i);
  }
  std::vector<int> seen(N, -1);
  for (int i = 0; i < n; ++i) {
    const Row& r = rows[static_cast<size_t>(i)];
    for (int body : {r.a, r.b}) {
      const BodyMass& m = mass[static_cast<size_t>(body)];
      if (m.invMass == 0 && m.invI.isZero()) continue;  // a static body couples nothing
      for (int k : rowsOf[static_cast<size_t>(body)]) {
        if (seen[static_cast<size_t>(k)] == i) continue;
        seen[static_cast<size_t>(k)] = i;
        p.A[static_cast<size_t>(i) * N + static_cast<size_t>(k)] = gammaEntry(r, rows[static_cast<size_t>(k)], mass.data());
      }
    }
    p.b[static_cast<size_t>(i)] = r.bias - rowVelocity(r, v, w);
    p.lo[static_cast<size_t>(i)] = r.lo;
    p.hi[static_cast<size_t>(i)] = r.hi;
    p.findex[static_cast<size_t>(i)] = r.normalRow;
    p.fcount[static_cast<size_t>(i)] = r.normalCount;
  }
}

namespace {

// (Γλ - b)_i: row i's velocity error at λ = x.
double rowResidual(const DenseMLCP& p, const std::vector<double>& x, int i) {
  const int n = p.n;
  double wi = -p.b[static_cast<size_t>(i)];
  for (int k = 0; k < n; ++k) wi += p.A[static_cast<size_t>(i * n + k)] * x[static_cast<size_t>(k)];
  return wi;
}

}  // namespace

double mlcpResidual(const DenseMLCP& p, const std::vector<double>& x) {
  const int n = p.n;
  double worst = 0;
  for (int i = 0; i < n; ++i) {
    const double wi = rowResidual(p, x, i);
    double lo, hi;
    bounds(p, x, i, lo, hi);
    const double d = p.A[static_cast<size_t>(i * n + i)];
    const double xi = x[static_cast<size_t>(i)];
    double r;
    if (d > 0) {
      r = d * std::abs(xi - std::clamp(xi - wi / d, lo, hi));
    } else {
      r = std::max({0.0, lo - xi, xi - hi});
    }
    worst = std::max(worst, r);
  }
  return worst;
}

namespace {

// The MLCP as an LCP for Lemke. Unbounded rows U are eliminated with the Schur complement of
// their block of Γ; every other row becomes complementarity variables:
//   lower bound only   λ = lo + z                     w = u
//   upper bound only   λ = hi - z                     w = -u
//   two bounds         λ = β⁺ - β⁻,  w⁺ = u + γ⁺,  w⁻ = -u + γ⁻,
//                      wγ⁺ = hi(λ) - β⁺,  wγ⁻ = -lo(λ) - β⁻    (friction: hi = -lo = μλn)
// with u = Γλ - b. Sliding shows as γ > 0: the velocity the friction bound cannot stop.
bool lemkeSolve(const DenseMLCP& p, std::vector<double>& x, Budget& budget) {
  const int n = p.n;
  Eigen::MatrixXd G(n, n);
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < n; ++k) G(i, k) = p.A[static_cast<size_t>(i * n + k)];
  const Eigen::VectorXd b = Eigen::Map<const Eigen::VectorXd>(p.b.data(), n);
  std::vector<int> U, R, local(static_cast<size_t>(n), -1);
  for (int i = 0; i < n; ++i) {
    const size_t s = static_cast<size_t>(i);
    if (p.findex[s] < 0 && std::isinf(p.lo[s]) && std::isinf(p.hi[s])) {
      U.push_back(i);
    } else {
      local[s] = static_cast<int>(R.size());
      R.push_back(i);
    }
  }
  const int nu = static_cast<int>(U.size()), nr = static_cast<int>(R.size());
  auto sub = [&](const std::vector<int>& rows, const std::vector<int>& cols) {
    Eigen::MatrixXd m(rows.size(), cols.size());
    for (size_t i = 0; i < rows.size(); ++i)
      for (size_t k = 0; k < cols.size(); ++k) m(static_cast<long>(i), static_cast<long>(k)) = G(rows[i], cols[k]);
    return m;
  };
  auto subv = [&](const std::vector<int>& rows) {
    Eigen::VectorXd v(rows.size());
    for (size_t i = 0; i < rows.size(); ++i) v[static_cast<long>(i)] = b[rows[i]];
    return v;
  };
  Eigen::MatrixXd Grr = sub(R, R);
  Eigen::VectorXd br = subv(R);
  Eigen::MatrixXd KinvGur;
  Eigen::VectorXd Kinvbu;
  if (nu > 0) {
    Eigen::MatrixXd K = sub(U, U);
    K.diagonal() *= 1.0 + 1e-12;
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(K);
    Kinvbu = lu.solve(subv(U));
    if (nr == 0) {  // equalities only: nothing to pivot (Eigen must not see an empty right side)
      x.assign(static_cast<size_t>(n), 0.0);
      for (int k = 0; k < nu; ++k) x[static_cast<size_t>(U[static_cast<size_t>(k)])] = Kinvbu[k];
      return true;
    }
    KinvGur = lu.solve(sub(U, R));
    Grr -= sub(R, U) * KinvGur;
    br -= sub(R, U) * Kinvbu;
  }
  // Variables of each reduced row.
  enum Kind { Lower, Upper, Box };
  std::vector<Kind> kind(static_cast<size_t>(nr));
  std::vector<int> var(static_cast<size_t>(nr));
  int nz = 0;
  for (int li = 0; li < nr; ++li) {
    const size_t s = static_cast<size_t>(R[static_cast<size_t>(li)]);
    const bool lo = !std::isinf(p.lo[s]), hi = !std::isinf(p.hi[s]);
    kind[static_cast<size_t>(li)] = p.findex[s] >= 0 || (lo && hi) ? Box : (lo ? Lower : Upper);
    var[static_cast<size_t>(li)] = nz;
    nz += kind[static_cast<size_t>(li)] == Box ? 4 : 1;
  }
  // λ_R = λ0 + P z
  Eigen::VectorXd lam0 = Eigen::VectorXd::Zero(nr);
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(nr, nz);
  for (int li = 0; li < nr; ++li) {
    const size_t s = static_cast<size_t>(R[static_cast<size_t>(li)]);
    const int v = var[static_cast<size_t>(li)];
    switch (kind[static_cast<size_t>(li)]) {
      case Lower: lam0[li] = p.lo[s]; P(li, v) = 1; break;
      case Upper: lam0[li] = p.hi[s]; P(li, v) = -1; break;
      case Box: P(li, v) = 1; P(li, v + 1) = -1; break;
    }
  }
  const Eigen::MatrixXd GP = Grr * P;
  const Eigen::VectorXd u0 = Grr * lam0 - br;
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(nz, nz);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(nz);
  for (int li = 0; li < nr; ++li) {
    const size_t s = static_cast<size_t>(R[static_cast<size_t>(li)]);
    const int v = var[static_cast<size_t>(li)];
    switch (kind[static_cast<size_t>(li)]) {
      case Lower: M.row(v) = GP.row(li); q[v] = u0[li]; break;
      case Upper: M.row(v) = -GP.row(li); q[v] = -u0[li]; break;
      case Box: {
        M.row(v) = GP.row(li);
        M(v, v + 2) += 1;
        q[v] = u0[li];
        M.row(v + 1) = -GP.row(li);
        M(v + 1, v + 3) += 1;
        q[v + 1] = -u0[li];
        M(v + 2, v) = -1;
        M(v + 3, v + 1) = -1;
        const int f = p.findex[s];
        if (f >= 0) {
          const double mu = std::abs(p.hi[s]);
          for (int k = 0; k < p.fcount[s]; ++k) {
            const int ln = local[static_cast<size_t>(f + k)];
            if (ln < 0) return false;
            M.row(v + 2) += mu * P.row(ln);
            M.row(v + 3) += mu * P.row(ln);
            q[v + 2] += mu * lam0[ln];
            q[v + 3] += mu * lam0[ln];
          }
        } else {
          q[v + 2] = p.hi[s];
          q[v + 3] = -p.lo[s];
        }
        break;
      }
    }
  }
  Eigen::VectorXd z;
  // Lemke's pivots are bounded: on the 1314 solves of the MLCP, stacking and claims tests that
  // found a solution, none took more pivots than its LCP has variables (at most 0.99 nz); those
  // that end on a ray take 2 to 4 times as many, each pivot O(nz²), which made a mass-ratio chain
  // spend minutes in one step. The cap leaves a factor of two.
  const double perPivot = 2.0 * nz * nz;
  const int pivots = static_cast<int>(std::min<double>(kLemkePivotsPerVariable * nz + 10, budget.left / perPivot));
  if (pivots < nz) return false;  // not even one pivot per variable: no hope within the budget
  const LemkeResult lr = lemke(M, q, z, pivots);
  budget.spend(lr.pivots * perPivot);
  if (!lr.ok) return false;
  const Eigen::VectorXd lamR = lam0 + P * z;
  x.assign(static_cast<size_t>(n), 0.0);
  for (int li = 0; li < nr; ++li) x[static_cast<size_t>(R[static_cast<size_t>(li)])] = lamR[li];
  if (nu > 0) {
    const Eigen::VectorXd lamU = Kinvbu - KinvGur * lamR;
    for (int k = 0; k < nu; ++k) x[static_cast<size_t>(U[static_cast<size_t>(k)])] = lamU[k];
  }
  return true;
}

// Given which rows sit on a bound, solves the equalities that define λ exactly (rows off their
// bounds: (Γλ - b)_i = 0; rows on them: λ_i = bound), removing the round-off a pivoting
// sequence leaves. Redundant rows (four points under one box) make the system singular: the
// minimum-norm solution is taken.
// Which rows sit on a bound is read from λ itself (within 1e-9 of it) first. When that leaves
// the residual above kDirectTolerance (a Gauss-Seidel answer to 5e-9, with rows whose λ is tiny
// but not on the bound), it is read from the projected Gauss-Seidel step instead, the natural
// map of semismooth Newton methods: row i is on a bound when λ_i - (Γλ - b)_i / Γ_ii is beyond it.
void polish(const DenseMLCP& p, std::vector<double>& x, Budget& budget) {
  const int n = p.n;
  Eigen::MatrixXd S(n, n);
  Eigen::VectorXd r(n);
  double best = mlcpResidual(p, x);
  const double perRound = 4.0 / 3.0 * std::pow(static_cast<double>(n), 3) + 2.0 * n * n;
  // A corrected λ can move a row across a bound: classify again from the better answer.
  auto rounds = [&](bool naturalMap) {
    for (int round = 0; round < 4 && best > 0 && budget.afford(perRound); ++round) {
      budget.spend(perRound);
      S.setZero();
      r.setZero();
      double scale = 0;
      for (double v : x) scale = std::max(scale, std::abs(v));
      const double tol = naturalMap ? 0.0 : 1e-9 * (1 + scale);
      for (int i = 0; i < n; ++i) {
        const size_t s = static_cast<size_t>(i);
        double lo, hi;
        bounds(p, x, i, lo, hi);
        double xi = x[s];
        const double d = p.A[static_cast<size_t>(i * n + i)];
        if (naturalMap && d > 0) xi -= rowResidual(p, x, i) / d;
        const int f = p.findex[s];
        if (xi <= lo + tol && !std::isinf(lo)) {
          S(i, i) = 1;  // λ = -μΣλn or lo
          if (f >= 0)
            for (int k = 0; k < p.fcount[s]; ++k) S(i, f + k) = std::abs(p.hi[s]);
          else
            r[i] = lo;
        } else if (xi >= hi - tol && !std::isinf(hi)) {
          S(i, i) = 1;  // λ = μΣλn or hi
          if (f >= 0)
            for (int k = 0; k < p.fcount[s]; ++k) S(i, f + k) = -std::abs(p.hi[s]);
          else
            r[i] = hi;
        } else {
          for (int k = 0; k < n; ++k) S(i, k) = p.A[static_cast<size_t>(i * n + k)];
          r[i] = p.b[s];
        }
      }
      const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(S);
      Eigen::VectorXd y = cod.solve(r);
      y += cod.solve(r - S * y);  // one step of iterative refinement
      std::vector<double> cand(y.data(), y.data() + n);
      const double res = mlcpResidual(p, cand);
      if (!(res < best)) break;
      best = res;
      x = cand;
    }
  };
  rounds(false);
  if (best > kDirectTolerance) rounds(true);
}

// Projected Gauss-Seidel on the dense problem, from x: the last resort when both pivoting
// methods fail, used only to find which rows sit on a bound; polish then makes it exact.
void densePgs(const DenseMLCP& p, std::vector<double>& x, int sweeps) {
  const int n = p.n;
  for (int it = 0; it < sweeps; ++it) {
    for (int i = 0; i < n; ++i) {
      const double d = p.A[static_cast<size_t>(i * n + i)];
      if (d <= 0) continue;
      const double wi = rowResidual(p, x, i);
      double lo, hi;
      bounds(p, x, i, lo, hi);
      x[static_cast<size_t>(i)] = std::clamp(x[static_cast<size_t>(i)] - wi / d, lo, hi);
    }
  }
}

}  // namespace

DirectResult solveDirect(const DenseMLCP& p, std::vector<double>& x, double workBudget, double cfm) {
  DirectResult res;
  Budget budget{workBudget};
  const double n = p.n;
  auto consider = [&](std::vector<double>& y, int method) {
    polish(p, y, budget);
    const double r = mlcpResidual(p, y);
    if (!res.ok || r < res.residual) {
      x = y;
      res.residual = r;
      res.ok = true;
      res.method = method;
    }
    return res.residual <= kDirectTolerance;
  };
  auto finish = [&] {
    res.work = workBudget - budget.left;
    return res;
  };
  // 1. ODE's Dantzig, exact for fixed bounds: friction first frictionless, then bounded by the
  //    normals of the previous solve, a few rounds while the normals settle.
  std::vector<double> y, normals(static_cast<size_t>(p.n), 0.0);
  const double perDantzig = n * n * n / 3 + n * n;
  for (int round = 0; round < 4 && budget.afford(perDantzig); ++round) {
    budget.spend(perDantzig);
    if (!dantzig(p, cfm, normals, y)) break;
    normals = y;
    if (round > 0 && consider(y, 1)) return finish();
  }
  // 2. Where those bounds disagree with the final normals: Lemke on the friction LCP.
  if (lemkeSolve(p, y, budget) && consider(y, 2)) return finish();
  // 3. Lemke can stop on a ray for friction LCPs that have a solution (they are not
  //    copositive-plus): Gauss-Seidel from the best answer finds the active set, polish solves it.
  //    Rounds of sweeps, each polished, about 4e7 multiply-adds in all.
  y.assign(static_cast<size_t>(p.n), 0.0);
  const int sweeps = static_cast<int>(std::clamp(4e6 / (n * n), 10.0, 10000.0));
  for (int round = 0; round < 10 && budget.afford(sweeps * n * n); ++round) {
    budget.spend(sweeps * n * n);
    densePgs(p, y, sweeps);
    std::vector<double> polished = y;
    if (consider(polished, 3)) break;
  }
  return finish();
}

}  // namespace substep

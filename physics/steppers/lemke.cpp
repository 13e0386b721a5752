#include "physics/steppers/lemke.h"

#include <cmath>
#include <vector>

namespace substep {

LemkeResult lemke(const Eigen::MatrixXd& M, const Eigen::VectorXd& q, Eigen::VectorXd& z, int maxPivots) {
  const int n = static_cast<int>(q.size());
  LemkeResult res;
  z = Eigen::VectorXd::Zero(n);
  if (n == 0 || q.minCoeff() >= 0) {
    res.ok = true;
    return res;
  }
  if (maxPivots <= 0) maxPivots = 50 * n + 100;
  // Tableau rows:  I w - M z - e z0 = q. Columns: w (0..n-1), z (n..2n-1), z0 (2n), rhs (2n+1).
  const int cz0 = 2 * n, crhs = 2 * n + 1;
  // Row-major: a pivot is row operations over the whole tableau.
  using Tableau = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  Tableau T = Tableau::Zero(n, 2 * n + 2);
  T.leftCols(n).setIdentity();
  T.block(0, n, n, n) = -M;
  T.col(cz0).setConstant(-1.0);
  T.col(crhs) = q;
  std::vector<int> basis(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) basis[static_cast<size_t>(i)] = i;
  const double scale = 1.0 + M.cwiseAbs().maxCoeff() + q.cwiseAbs().maxCoeff();
  const double eps = 1e-13 * scale;

  auto pivot = [&](int r, int c) {
    const double d = T(r, c);  // copied: the row operation overwrites T(r, c)
    T.row(r) /= d;
    for (int i = 0; i < n; ++i) {
      const double f = T(i, c);
      if (i != r && f != 0) T.row(i) -= f * T.row(r);
    }
    basis[static_cast<size_t>(r)] = c;
  };

  // Leaving row for entering column c: the minimum ratio rhs/T(i,c) over T(i,c) > 0, ties broken
  // lexicographically by the rows of the basis inverse (the w columns), preferring z0 to leave.
  std::vector<int> cand, next;
  auto ratioTest = [&](int c) {
    cand.clear();
    double best = INFINITY;
    for (int i = 0; i < n; ++i) {
      if (T(i, c) <= eps) continue;
      const double r = T(i, crhs) / T(i, c);
      if (cand.empty() || r < best - 1e-12 * (1 + std::abs(best))) {
        best = r;
        cand.assign(1, i);
      } else if (r <= best + 1e-12 * (1 + std::abs(best))) {
        cand.push_back(i);
      }
    }
    if (cand.empty()) return -1;
    for (int i : cand)
      if (basis[static_cast<size_t>(i)] == cz0) return i;
    for (int k = 0; k < n && cand.size() > 1; ++k) {
      double lo = INFINITY;
      for (int i : cand) lo = std::min(lo, T(i, k) / T(i, c));
      next.clear();
      for (int i : cand)
        if (T(i, k) / T(i, c) <= lo + 1e-12 * (1 + std::abs(lo))) next.push_back(i);
      cand.swap(next);
    }
    return cand.front();
  };

  // z0 enters at the row of the most negative q.
  int r = 0;
  for (int i = 1; i < n; ++i)
    if (q[i] < q[r]) r = i;
  int leaving = basis[static_cast<size_t>(r)];
  pivot(r, cz0);
  res.pivots = 1;
  while (res.pivots < maxPivots) {
    const int entering = leaving < n ? leaving + n : leaving - n;  // the complement
    r = ratioTest(entering);
    if (r < 0) return res;  // ray termination
    leaving = basis[static_cast<size_t>(r)];
    pivot(r, entering);
    ++res.pivots;
    if (leaving == cz0) {
      for (int i = 0; i < n; ++i) {
        const int b = basis[static_cast<size_t>(i)];
        if (b >= n && b < 2 * n) z[b - n] = std::max(0.0, T(i, crhs));
      }
      res.ok = true;
      return res;
    }
  }
  return res;
}

}  // namespace substep

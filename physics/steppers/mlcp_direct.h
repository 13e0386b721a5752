// A1's direct solve of the MLCP  Γλ = β - J̌v̌ + w  with bounds (the report's C, section II.3):
// ODE's Dantzig pivoting solver as DART packages it (libdart-external-odelcpsolver), for fixed
// friction bounds re-set from the normals a few rounds; where the bounds still disagree with the
// normal impulses, Lemke's method on the friction LCP (lemke.h); where Lemke stops on a ray,
// Gauss-Seidel finds the active set.
// Every answer is polished: the equalities of its active set solved exactly.
#pragma once

#include "physics/constraints/row.h"

#include <vector>

namespace substep {

struct DenseMLCP {
  int n = 0;
  std::vector<double> A;        // n x n, row-major (Γ)
  std::vector<double> b;        // right-hand side β - J̌v̌
  std::vector<double> lo, hi;   // bounds; for friction rows the coefficient ±μ
  std::vector<int> findex;      // friction row -> its first normal row, else -1
  std::vector<int> fcount;      // friction row -> how many normal rows (contiguous) bound it
};

// Γ = J̌M̌⁻¹J̌ᵀ (entries only where rows share a body), b = β - J̌v̌ and the bounds, from rows.
void assembleMLCP(const std::vector<Row>& rows, const std::vector<BodyMass>& mass, const Vec3* v, const Vec3* w,
                  DenseMLCP& out);

// Lemke's method stops after this many pivots per variable of its LCP (docs/algorithms.md).
constexpr int kLemkePivotsPerVariable = 2;

// A1's work per step is counted in floating-point operations estimated from the problem's size
// (Dantzig n³/3, a polish 4n³/3, a Lemke pivot 2nz², a sweep n²); the budget is
// SolverSettings::directWorkBudget (2e10 by default, about 3 s on this machine). Within it the
// solver chain stops at the first exact answer; beyond it, it keeps the best answer so far.

// The residual A1 aims for [m/s].
constexpr double kDirectTolerance = 1e-10;

struct DirectResult {
  bool ok = false;
  int method = 0;               // what gave the answer: 1 Dantzig, 2 Lemke, 3 Gauss-Seidel + polish
  double residual = 0;          // mlcpResidual of the answer
  double work = 0;              // floating-point operations spent, estimated (at most the budget)
};

// Solves p for λ (size n). Γ is regularised by cfm times its diagonal so that redundant
// contact rows (four points and their friction on one box) keep the pivots finite.
DirectResult solveDirect(const DenseMLCP& p, std::vector<double>& lambda, double workBudget = 2e10,
                         double cfm = 1e-12);

// Natural residual scaled to velocity: max_i Γ_ii |λ_i - clamp(λ_i - w_i/Γ_ii, lo_i, hi_i)| with
// w = Γλ - b and friction bounds μλ of the row's normal. Zero exactly at a solution.
double mlcpResidual(const DenseMLCP& p, const std::vector<double>& lambda);

}  // namespace substep

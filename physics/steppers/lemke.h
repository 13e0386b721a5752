// Lemke's complementary pivoting for the LCP  w = M z + q,  w >= 0, z >= 0, wᵀz = 0,
// with a lexicographic ratio test so degenerate problems (redundant contact points) do not cycle.
// The project's own: Debian packages no Lemke solver but Siconos, whose 270 MB of dependencies
// and broken CMake config are not worth one pivoting loop (docs/dependencies.md).
#pragma once

#include <Eigen/Core>

namespace substep {

struct LemkeResult {
  bool ok = false;   // false on ray termination or when the pivot cap is reached
  int pivots = 0;
};

LemkeResult lemke(const Eigen::MatrixXd& M, const Eigen::VectorXd& q, Eigen::VectorXd& z, int maxPivots = 0);

}  // namespace substep

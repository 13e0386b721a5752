// Two rows the same field for field, each double to the last bit (+0 and -0 differ), for tests
// that hold two ways of making a row to the same numbers.
#pragma once

#include "physics/constraints/row.h"

#include <gtest/gtest.h>

#include <cstring>
#include <string>

namespace substep {

inline bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// r and d equal field for field (what names them in a failure).
inline void expectSameRow(const Row& r, const Row& d, const std::string& what) {
  const auto same = [&](double x, double y, const char* field) {
    EXPECT_TRUE(sameBits(x, y)) << what << " " << field << ": " << x << " against " << y;
  };
  EXPECT_EQ(r.a, d.a) << what;
  EXPECT_EQ(r.b, d.b) << what;
  for (int i = 0; i < 3; ++i) {
    same(r.lin[i], d.lin[i], "lin");
    same(r.angA[i], d.angA[i], "angA");
    same(r.angB[i], d.angB[i], "angB");
    same(r.mAngA[i], d.mAngA[i], "mAngA");
    same(r.mAngB[i], d.mAngB[i], "mAngB");
  }
  same(r.mA, d.mA, "mA");
  same(r.mB, d.mB, "mB");
  same(r.effMass, d.effMass, "effMass");
  same(r.bias, d.bias, "bias");
  same(r.lo, d.lo, "lo");
  same(r.hi, d.hi, "hi");
  same(r.split, d.split, "split");
  same(r.lambda, d.lambda, "lambda");
  EXPECT_EQ(r.normalRow, d.normalRow) << what;
  EXPECT_EQ(r.normalCount, d.normalCount) << what;
  EXPECT_EQ(r.velocityLevel, d.velocityLevel) << what;
  EXPECT_EQ(r.velocityTarget, d.velocityTarget) << what;
  EXPECT_EQ(r.speculative, d.speculative) << what;
  EXPECT_EQ(r.pushed, d.pushed) << what;
}

}  // namespace substep

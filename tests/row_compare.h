// Two rows the same field for field, each double to the last bit (+0 and -0 differ), for tests
// that hold two ways of making a row to the same numbers.
#pragma once

#include "physics/constraints/row.h"

#include <gtest/gtest.h>

#include <cstring>
#include <sstream>
#include <string>

namespace substep {

inline bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// The fields in which r and d differ, with both values ("" when none).
inline std::string rowDifferences(const Row& r, const Row& d) {
  std::ostringstream out;
  const auto same = [&](double x, double y, const char* field) {
    if (!sameBits(x, y)) out << " " << field << ": " << x << " against " << y << ";";
  };
  const auto equal = [&](auto x, auto y, const char* field) {
    if (x != y) out << " " << field << ": " << x << " against " << y << ";";
  };
  equal(r.a, d.a, "a");
  equal(r.b, d.b, "b");
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
  equal(r.normalRow, d.normalRow, "normalRow");
  equal(r.normalCount, d.normalCount, "normalCount");
  equal(r.velocityLevel, d.velocityLevel, "velocityLevel");
  equal(r.velocityTarget, d.velocityTarget, "velocityTarget");
  equal(r.speculative, d.speculative, "speculative");
  equal(r.pushed, d.pushed, "pushed");
  return out.str();
}

// r and d equal field for field (what names them in a failure).
inline void expectSameRow(const Row& r, const Row& d, const std::string& what) {
  EXPECT_EQ(rowDifferences(r, d), "") << what;
}

}  // namespace substep

// substep-bench's printed ratios (app/bench/ratio_text.h): what a target's line shows must not
// contradict its MET or NOT MET; and the speed-up --core-check says the cores allow, and how
// long its cores take to hand a cache line over.
#include "app/bench/core_bound.h"
#include "app/bench/core_handover.h"
#include "app/bench/ratio_text.h"

#include <sched.h>

#include <gtest/gtest.h>

using namespace substep::bench;

TEST(BenchText, ARatioIsPrintedToTwoPlaces) {
  EXPECT_EQ(ratioText(Ratio{0.3612, 0.349, 0.3749}), "0.36x (0.35-0.37)");
  EXPECT_EQ(ratioText(Ratio{0.3612, 0.349, 0.3749}, 1.6), "0.36x (0.35-0.37)");
  EXPECT_EQ(ratioText(Ratio{}), "-");
}

// A speed-up of 1.5996 against "at least 1.60x" is NOT MET; two places would print it as 1.60x.
TEST(BenchText, ARatioThatTwoPlacesRoundOntoItsBoundIsPrintedToFour) {
  EXPECT_EQ(ratioText(Ratio{1.5996, 1.44, 1.74}, 1.6), "1.5996x (1.4400-1.7400)");
  EXPECT_EQ(ratioText(Ratio{0.3504, 0.35, 0.351}, 0.35), "0.3504x (0.3500-0.3510)");
  EXPECT_EQ(ratioText(Ratio{1.5996, 1.44, 1.74}), "1.60x (1.44-1.74)");  // no bound: two places
}

// --core-check's bound (app/bench/core_bound.h): N threads at best share the work in proportion
// to each core's own speed, on the N fastest cores.
TEST(BenchCores, EqualCoresAllowNTimesOne) {
  EXPECT_DOUBLE_EQ(coreBound({10.0, 10.0}, 2), 5.0);
  EXPECT_DOUBLE_EQ(coreBound({10.0, 10.0, 10.0, 10.0}, 4), 2.5);
  EXPECT_DOUBLE_EQ(coreBound({10.0}, 1), 10.0);
}

// Two vCPUs of this project's machine, measured: a core a third slower caps two threads at
// 1.76x of the faster one, not 2x.
TEST(BenchCores, ASlowerCoreLowersTheBound) {
  const double best = coreBound({13.614, 10.333}, 2);
  EXPECT_NEAR(best, 1 / (1 / 13.614 + 1 / 10.333), 1e-12);
  EXPECT_NEAR(10.333 / best, 1.759, 1e-3);
}

TEST(BenchCores, OnlyTheFastestNCoresCountAndNoneIsNaN) {
  EXPECT_DOUBLE_EQ(coreBound({40.0, 10.0, 10.0}, 2), 5.0);  // order given does not matter
  EXPECT_DOUBLE_EQ(coreBound({10.0, 10.0}, 8), 5.0);        // more threads than cores timed
  EXPECT_TRUE(std::isnan(coreBound({}, 2)));
  EXPECT_TRUE(std::isnan(coreBound({10.0}, 0)));
}

// --core-check's hand-over (app/bench/core_handover.h) between the first two cores this process
// may run on: a real round trip through the caches, some tens of nanoseconds at least (one that
// did not wait for the other thread would take a few), and the caller's cores given back.
TEST(BenchCores, TwoCoresHandACacheLineOverAndBack) {
  cpu_set_t before;
  ASSERT_EQ(sched_getaffinity(0, sizeof before, &before), 0);
  std::vector<int> cores;
  for (int c = 0; c < CPU_SETSIZE && cores.size() < 2; ++c)
    if (CPU_ISSET(c, &before)) cores.push_back(c);
  if (cores.size() < 2) {
    GTEST_SKIP() << "one core only";
  }
  const double roundTrip = cacheLineRoundTrip(cores[0], cores[1], 500, 5);
  EXPECT_GT(roundTrip, 10.0);
  EXPECT_LT(roundTrip, 1e6);
  cpu_set_t after;
  ASSERT_EQ(sched_getaffinity(0, sizeof after, &after), 0);
  EXPECT_TRUE(CPU_EQUAL(&before, &after));
  EXPECT_TRUE(std::isnan(cacheLineRoundTrip(cores[0], cores[0])));  // one core cannot hand over to itself
  // A core this process may not run on: no figure, and no wait for a thread that never starts.
  int barred = -1;
  for (int c = 0; c < CPU_SETSIZE && barred < 0; ++c)
    if (!CPU_ISSET(c, &before)) barred = c;
  if (barred >= 0) {
    EXPECT_TRUE(std::isnan(cacheLineRoundTrip(cores[0], barred)));
  }
}

// substep-bench's printed ratios (app/bench/ratio_text.h): what a target's line shows must not
// contradict its MET or NOT MET.
#include "app/bench/ratio_text.h"

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

#include "superdyna/core/time.h"

#include <gtest/gtest.h>

namespace superdyna {
namespace {

TEST(TimeTest, ParsesDecimalSecondsExactly) {
  EXPECT_EQ(parseSecondsToNs("1403636580.83856"), 1403636580838560000LL);
  EXPECT_EQ(parseSecondsToNs("1563003603.73554158"), 1563003603735541580LL);
  EXPECT_EQ(parseSecondsToNs("12"), 12'000'000'000LL);
  EXPECT_EQ(parseSecondsToNs(".5"), 500'000'000LL);
  EXPECT_EQ(parseSecondsToNs("-0.25"), -250'000'000LL);
  EXPECT_EQ(parseSecondsToNs("0.0000000015"), 2LL);  // tenth decimal rounds half up
}

TEST(TimeTest, ParsesExponentNotation) {
  EXPECT_EQ(parseSecondsToNs("1.037359e-01"), 103'735'900LL);
  EXPECT_EQ(parseSecondsToNs("0.000000e+00"), 0LL);
}

TEST(TimeTest, RejectsMalformedText) {
  EXPECT_FALSE(parseSecondsToNs(""));
  EXPECT_FALSE(parseSecondsToNs("."));
  EXPECT_FALSE(parseSecondsToNs("1.2.3"));
  EXPECT_FALSE(parseSecondsToNs("abc"));
  EXPECT_FALSE(parseSecondsToNs("nan"));
  EXPECT_FALSE(parseSecondsToNs("1e400"));
  EXPECT_FALSE(parseSecondsToNs("99999999999"));
  // Ten digits that overflow int64 nanoseconds (signed overflow before; fuzz/trajectory_fuzzer).
  EXPECT_FALSE(parseSecondsToNs("9999999999"));
  EXPECT_FALSE(parseSecondsToNs("-9223372036.5"));
  EXPECT_EQ(parseSecondsToNs("9223372035.999999999"), 9223372035999999999LL);
}

TEST(TimeTest, FormatsWithNineDecimalsAndRoundTrips) {
  EXPECT_EQ(formatNsAsSeconds(1403715273262142976LL), "1403715273.262142976");
  EXPECT_EQ(formatNsAsSeconds(-250'000'000LL), "-0.250000000");
  for (TimeNs t : {0LL, 1LL, 999'999'999LL, 1403715273312143104LL, -7LL}) {
    EXPECT_EQ(parseSecondsToNs(formatNsAsSeconds(t)), t);
  }
}

}  // namespace
}  // namespace superdyna

#include "superdyna/eval/statistics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "superdyna/core/error.h"
#include "superdyna/eval/multi_run.h"

namespace superdyna::eval {
namespace {

TEST(StatisticsTest, KnownNumbersWithEvenCount) {
  const std::vector<double> values = {4.0, 1.0, 3.0, 2.0};
  const ErrorStatistics s = computeStatistics(values);
  EXPECT_EQ(s.count, 4u);
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);           // mean of the two middle values
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(1.25));  // population: divides by n (numpy, evo)
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(30.0 / 4.0));
  EXPECT_DOUBLE_EQ(s.min, 1.0);
  EXPECT_DOUBLE_EQ(s.max, 4.0);
}

TEST(StatisticsTest, MedianOfOddCountAndSingleValue) {
  EXPECT_DOUBLE_EQ(median(std::vector<double>{5.0, 1.0, 3.0}), 3.0);
  const ErrorStatistics one = computeStatistics(std::vector<double>{0.7});
  EXPECT_DOUBLE_EQ(one.median, 0.7);
  EXPECT_DOUBLE_EQ(one.rmse, 0.7);
  EXPECT_DOUBLE_EQ(one.std, 0.0);
}

TEST(StatisticsTest, EmptyInputIsAnError) {
  EXPECT_THROW(computeStatistics(std::vector<double>{}), InputError);
  EXPECT_THROW(median(std::vector<double>{}), InputError);
  EXPECT_THROW(summarizeRunValues({}), InputError);
}

TEST(StatisticsTest, SampleStandardDeviationDividesByNMinusOne) {
  const std::vector<double> values = {1.0, 2.0, 3.0, 4.0};
  EXPECT_DOUBLE_EQ(sampleStandardDeviation(values), std::sqrt(5.0 / 3.0));
  EXPECT_TRUE(std::isnan(sampleStandardDeviation(std::vector<double>{1.0})));
}

TEST(StatisticsTest, StudentTQuantilesMatchTables) {
  EXPECT_NEAR(studentTQuantile(0.95, 4), 2.7764451051977987, 1e-12);
  EXPECT_NEAR(studentTQuantile(0.95, 1), 12.706204736174698, 1e-10);
  EXPECT_NEAR(studentTQuantile(0.95, 1000), 1.9623390808264078, 1e-10);
  EXPECT_THROW(studentTQuantile(0.95, 0), OptionError);
  EXPECT_THROW(studentTQuantile(1.0, 3), OptionError);
}

TEST(StatisticsTest, ConfidenceHalfWidthOfFiveRuns) {
  const std::vector<double> ate = {0.031, 0.027, 0.035, 0.029, 0.042};
  double mean = 0.0;
  for (double v : ate)
    mean += v / 5.0;
  double squares = 0.0;
  for (double v : ate)
    squares += (v - mean) * (v - mean);
  const double s = std::sqrt(squares / 4.0);
  const double expected = 2.7764451051977987 * s / std::sqrt(5.0);
  EXPECT_NEAR(confidenceHalfWidth(ate), expected, 1e-15);

  const RunStatistics summary = summarizeRunValues(ate);
  EXPECT_EQ(summary.runs, 5u);
  EXPECT_DOUBLE_EQ(summary.median, 0.031);
  EXPECT_NEAR(summary.mean, mean, 1e-15);
  EXPECT_NEAR(summary.std, s, 1e-15);
  EXPECT_NEAR(summary.ci95_halfwidth, expected, 1e-15);
}

TEST(StatisticsTest, SingleRunHasNoIntervalButDoesNotFail) {
  const RunStatistics summary = summarizeRunValues({0.05});
  EXPECT_EQ(summary.runs, 1u);
  EXPECT_DOUBLE_EQ(summary.median, 0.05);
  EXPECT_DOUBLE_EQ(summary.mean, 0.05);
  EXPECT_TRUE(std::isnan(summary.std));
  EXPECT_TRUE(std::isnan(summary.ci95_halfwidth));
}

}  // namespace
}  // namespace superdyna::eval

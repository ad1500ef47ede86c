#include "superdyna/features/xfeat_matcher.h"

#include <gtest/gtest.h>

#include <numeric>

#include "superdyna/core/error.h"
#include "support/test_support.h"

namespace superdyna::features {
namespace {

using test::expectError;

/// `rows` random unit vectors of length `cols` (seeded).
cv::Mat randomUnitRows(int rows, int cols, std::uint64_t seed) {
  cv::Mat m(rows, cols, CV_32FC1);
  cv::RNG rng(seed);
  rng.fill(m, cv::RNG::NORMAL, 0.0, 1.0);
  for (int i = 0; i < rows; ++i)
    cv::normalize(m.row(i), m.row(i));
  return m;
}

TEST(MatchFloatMutualNN, RecoversAPermutationWithExactDistances) {
  const cv::Mat query = randomUnitRows(200, 64, 1);
  std::vector<int> permutation(200);
  std::iota(permutation.begin(), permutation.end(), 0);
  cv::RNG rng(2);
  for (int i = 199; i > 0; --i)
    std::swap(permutation[i], permutation[rng.uniform(0, i + 1)]);
  cv::Mat train(200, 64, CV_32FC1);
  cv::Mat noise(1, 64, CV_32FC1);
  for (int i = 0; i < 200; ++i) {
    rng.fill(noise, cv::RNG::NORMAL, 0.0, 0.01);
    train.row(permutation[static_cast<std::size_t>(i)]) = query.row(i) + noise;
  }
  const auto matches = matchFloatMutualNN(query, train, 0.8);
  ASSERT_EQ(matches.size(), 200u);
  for (int i = 0; i < 200; ++i) {
    const FloatMatch& m = matches[static_cast<std::size_t>(i)];
    EXPECT_EQ(m.query, i);
    EXPECT_EQ(m.train, permutation[static_cast<std::size_t>(i)]);
    EXPECT_NEAR(m.distance, cv::norm(query.row(m.query), train.row(m.train)), 1e-5);
  }
}

TEST(MatchFloatMutualNN, KeepsOnlyMutualMatchesThatPassTheRatioTest) {
  // Queries 0 and 1 both prefer train 0, which prefers query 1; query 2 is ambiguous between
  // train 1 and train 2 (distances 1.0 and 1.05).
  const cv::Mat query = (cv::Mat_<float>(3, 2) << 0.0f, 0.5f, 0.0f, 0.1f, 10.0f, 0.0f);
  const cv::Mat train = (cv::Mat_<float>(3, 2) << 0.0f, 0.0f, 10.0f, 1.0f, 10.0f, -1.05f);
  auto matches = matchFloatMutualNN(query, train, 1.0);
  ASSERT_EQ(matches.size(), 2u);
  EXPECT_EQ(matches[0].query, 1);
  EXPECT_EQ(matches[0].train, 0);
  EXPECT_NEAR(matches[0].distance, 0.1f, 1e-6);
  EXPECT_EQ(matches[1].query, 2);
  EXPECT_EQ(matches[1].train, 1);
  matches = matchFloatMutualNN(query, train, 0.9);  // 1.0 < 0.9 * 1.05 fails
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].query, 1);
}

TEST(MatchFloatMutualNN, TiesGoToTheLowerIndex) {
  const cv::Mat query = (cv::Mat_<float>(1, 2) << 0.0f, 0.0f);
  const cv::Mat train = (cv::Mat_<float>(2, 2) << 1.0f, 0.0f, 0.0f, 1.0f);
  const auto matches = matchFloatMutualNN(query, train);
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].train, 0);
}

TEST(MatchFloatMutualNN, RejectsBadInput) {
  const cv::Mat a = randomUnitRows(3, 8, 3), b = randomUnitRows(3, 16, 4);
  expectError([&] { matchFloatMutualNN(a, b); }, {"equal length"});
  cv::Mat bytes(3, 8, CV_8UC1, cv::Scalar(0));
  expectError([&] { matchFloatMutualNN(a, bytes); }, {"CV_32FC1"});
  expectError<OptionError>([&] { matchFloatMutualNN(a, a, 0.0); }, {"ratio"});
  EXPECT_TRUE(matchFloatMutualNN(cv::Mat(), a).empty());
  FeatureSet binary, floats;
  floats.descriptor_type = DescriptorType::kFloat;
  expectError([&] { matchFloatMutualNN(binary, floats); }, {"float descriptors"});
}

}  // namespace
}  // namespace superdyna::features

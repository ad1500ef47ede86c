#include "superdyna/features/matcher.h"

#include <gtest/gtest.h>

#include <iostream>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <random>
#include <tuple>

#include "feature_test_util.h"
#include "superdyna/core/error.h"
#include "superdyna/features/orb_extractor.h"

namespace superdyna::features {
namespace {

FeatureSet binarySet(const std::vector<std::vector<std::uint8_t>>& rows) {
  FeatureSet set;
  set.descriptors = cv::Mat(static_cast<int>(rows.size()), 4, CV_8UC1);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    for (int b = 0; b < 4; ++b)
      set.descriptors.at<std::uint8_t>(static_cast<int>(i), b) =
          rows[i][static_cast<std::size_t>(b)];
    Keypoint kp;
    kp.pixel = Eigen::Vector2d(10.0 * static_cast<double>(i), 5.0);
    kp.angle = 0.0f;
    set.keypoints.push_back(kp);
  }
  return set;
}

TEST(FeatureSetTest, ValidatesAndSelects) {
  FeatureSet set = binarySet({{1, 2, 3, 4}, {5, 6, 7, 8}, {9, 10, 11, 12}});
  EXPECT_NO_THROW(set.validate());
  const FeatureSet picked = set.select({2, 0});
  ASSERT_EQ(picked.size(), 2u);
  EXPECT_EQ(picked.keypoints[0].pixel, set.keypoints[2].pixel);
  EXPECT_EQ(picked.descriptors.at<std::uint8_t>(0, 0), 9);
  EXPECT_EQ(picked.descriptors.at<std::uint8_t>(1, 3), 4);
  set.keypoints.pop_back();
  EXPECT_THROW(set.validate(), InputError);
  set = binarySet({{1, 2, 3, 4}});
  set.descriptor_type = DescriptorType::kFloat;
  EXPECT_THROW(set.validate(), InputError);
  EXPECT_EQ(toString(DescriptorType::kBinary), "binary");
}

TEST(HammingTest, CountsDifferingBits) {
  const std::uint8_t a[33] = {0xFF, 0x00, 0x0F};
  std::uint8_t b[33] = {0x00, 0x00, 0x0E};
  EXPECT_EQ(hammingDistance(a, b, 33), 9);
  b[32] = 0x81;
  EXPECT_EQ(hammingDistance(a, b, 33), 11);
  EXPECT_EQ(hammingDistance(a, a, 33), 0);
  cv::Mat x(1, 32, CV_8UC1, cv::Scalar(0xFF)), y(1, 32, CV_8UC1, cv::Scalar(0));
  EXPECT_EQ(hammingDistance(x, y), 256);
  EXPECT_THROW(hammingDistance(x, cv::Mat(1, 16, CV_8UC1)), InputError);
}

TEST(BruteForceMatcherTest, AppliesDistanceRatioAndMutualChecks) {
  const FeatureSet query = binarySet({{0, 0, 0, 0}, {0xFF, 0xFF, 0, 0}, {0xF0, 0, 0, 0}});
  const FeatureSet train = binarySet(
      {{0x01, 0, 0, 0}, {0xFF, 0xFF, 0x01, 0}, {0xFF, 0xFF, 0x03, 0}, {0xF0, 0x0F, 0, 0}});
  BruteForceMatchOptions options;
  options.max_distance = 8;
  options.ratio = 0.9;
  std::vector<Match> matches = matchBruteForce(query, train, options);
  // q0 -> t0 (1 bit, next best 4); q1 -> t1 (1) vs t2 (2): ratio 0.5 passes;
  // q2 -> t0 (5) vs t3 (4): t3 wins with 4 but t3's nearest query is q2 -> kept.
  ASSERT_EQ(matches.size(), 3u);
  EXPECT_EQ(matches[0].train, 0);
  EXPECT_EQ(matches[0].distance, 1);
  EXPECT_EQ(matches[1].train, 1);
  EXPECT_EQ(matches[2].train, 3);
  EXPECT_EQ(matches[2].distance, 4);
  options.max_distance = 3;
  EXPECT_EQ(matchBruteForce(query, train, options).size(), 2u);
  options.ratio = 0.4;  // q1: 1 < 0.4 * 2 fails; q0: 1 < 0.4 * 4 passes
  EXPECT_EQ(matchBruteForce(query, train, options).size(), 1u);
  options.ratio = 0.0;
  EXPECT_THROW(matchBruteForce(query, train, options), OptionError);
  FeatureSet floats = query;
  floats.descriptor_type = DescriptorType::kFloat;
  floats.descriptors.convertTo(floats.descriptors, CV_32F);
  EXPECT_THROW(matchBruteForce(floats, train), InputError);
}

TEST(OrientationCheckTest, KeepsTheDominantRotations) {
  std::vector<Keypoint> query(100), train(100);
  std::vector<Match> matches;
  std::mt19937 rng(3);
  for (int i = 0; i < 100; ++i) {
    query[static_cast<std::size_t>(i)].angle = static_cast<float>(rng() % 360);
    // 80 matches rotated by about 40 degrees (+-3), 20 at random rotations.
    const double rotation = i < 80 ? 40.0 + static_cast<int>(rng() % 7) - 3 : (rng() % 360);
    train[static_cast<std::size_t>(i)].angle = static_cast<float>(
        std::fmod(query[static_cast<std::size_t>(i)].angle - rotation + 720.0, 360.0));
    matches.push_back({i, i, 0});
  }
  const std::vector<Match> kept = filterByOrientation(matches, query, train);
  int consistent = 0;
  for (const Match& m : kept)
    consistent += m.query < 80;
  EXPECT_EQ(consistent, 80);
  EXPECT_LE(kept.size(), 86u);
  // Keypoints without orientation never pass.
  query[0].angle = -1.0f;
  EXPECT_EQ(filterByOrientation({{0, 0, 0}}, query, train).size(), 0u);
}

TEST(KeypointGridTest, RadiusQueriesAgreeWithAnExhaustiveSearch) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> x(-5.0, 757.0), y(-5.0, 485.0);
  std::vector<Keypoint> keypoints(3000);
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    keypoints[i].pixel = Eigen::Vector2d(x(rng), y(rng));
    keypoints[i].octave = static_cast<int>(i % 4);
  }
  const KeypointGrid grid(keypoints, cv::Size(752, 480), 20);
  EXPECT_EQ(grid.size(), keypoints.size());
  for (int q = 0; q < 200; ++q) {
    const Eigen::Vector2d c(x(rng), y(rng));
    const double r = 1.0 + (q % 40);
    std::vector<int> expected;
    for (std::size_t i = 0; i < keypoints.size(); ++i) {
      if ((keypoints[i].pixel - c).norm() <= r && keypoints[i].octave >= 1 &&
          keypoints[i].octave <= 2) {
        expected.push_back(static_cast<int>(i));
      }
    }
    EXPECT_EQ(grid.within(c, r, 1, 2), expected);
  }
  EXPECT_THROW(KeypointGrid(keypoints, cv::Size(752, 480), 0), OptionError);
}

TEST(KeypointGridTest, ASubsetGridFindsOnlyTheIncludedKeypointsByTheirOwnIndices) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> x(0.0, 752.0), y(0.0, 480.0);
  std::vector<Keypoint> keypoints(2000);
  std::vector<char> include(keypoints.size());
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    keypoints[i].pixel = Eigen::Vector2d(x(rng), y(rng));
    include[i] = i % 3 == 0;
  }
  const KeypointGrid grid(keypoints, cv::Size(752, 480), 60, include);
  EXPECT_EQ(grid.size(), keypoints.size());
  for (int q = 0; q < 100; ++q) {
    const Eigen::Vector2d c(x(rng), y(rng));
    const double r = 10.0 + q;
    std::vector<int> expected;
    for (std::size_t i = 0; i < keypoints.size(); ++i) {
      if (include[i] && (keypoints[i].pixel - c).norm() <= r)
        expected.push_back(static_cast<int>(i));
    }
    EXPECT_EQ(grid.within(c, r), expected);
  }
  EXPECT_THROW(KeypointGrid(keypoints, cv::Size(752, 480), 20, std::vector<char>(5, 1)),
               InputError);
}

TEST(ProjectionMatcherTest, EqualDistancesGoToTheLowerTrainIndexWhateverTheCellOrder) {
  // Train 0 lies in a later grid row than train 1; both carry the query's descriptor.
  FeatureSet query, train;
  query.image_size = train.image_size = cv::Size(752, 480);
  query.descriptor_type = train.descriptor_type = DescriptorType::kBinary;
  query.keypoints.resize(1);
  query.keypoints[0].pixel = Eigen::Vector2d(100.0, 100.0);
  query.descriptors = cv::Mat(1, 32, CV_8UC1, cv::Scalar(0x5a));
  train.keypoints.resize(2);
  train.keypoints[0].pixel = Eigen::Vector2d(100.0, 140.0);
  train.keypoints[1].pixel = Eigen::Vector2d(100.0, 60.0);
  train.descriptors = cv::Mat(2, 32, CV_8UC1, cv::Scalar(0x5a));
  const KeypointGrid grid(train.keypoints, train.image_size, 20);
  ProjectionMatchOptions options;
  options.radius_px = 50.0;
  options.ratio = 1.0;
  options.check_orientation = false;
  const std::vector<Match> matches =
      matchByProjection(query, {Eigen::Vector2d(100.0, 100.0)}, train, grid, options);
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].train, 0);
}

/// One query keypoint at (100, 100) and the train keypoints given as (x offset, octave, descriptor
/// byte), all at y = 100 with 32-byte descriptors filled with that byte.
struct ProjectionCase {
  FeatureSet query, train;
  ProjectionCase(int query_octave, const std::vector<std::tuple<double, int, std::uint8_t>>& rows) {
    query.image_size = train.image_size = cv::Size(752, 480);
    query.descriptor_type = train.descriptor_type = DescriptorType::kBinary;
    query.keypoints.resize(1);
    query.keypoints[0].pixel = Eigen::Vector2d(100.0, 100.0);
    query.keypoints[0].octave = query_octave;
    query.descriptors = cv::Mat(1, 32, CV_8UC1, cv::Scalar(0));
    train.descriptors = cv::Mat(static_cast<int>(rows.size()), 32, CV_8UC1);
    for (std::size_t j = 0; j < rows.size(); ++j) {
      const auto& [dx, octave, byte] = rows[j];
      Keypoint kp;
      kp.pixel = Eigen::Vector2d(100.0 + dx, 100.0);
      kp.octave = octave;
      train.keypoints.push_back(kp);
      train.descriptors.row(static_cast<int>(j)).setTo(cv::Scalar(byte));
    }
  }
  /// The train index matched, or -1.
  int match(const ProjectionMatchOptions& options) const {
    const KeypointGrid grid(train.keypoints, train.image_size);
    const std::vector<Match> m =
        matchByProjection(query, {Eigen::Vector2d(100.0, 100.0)}, train, grid, options);
    return m.empty() ? -1 : m[0].train;
  }
};

ProjectionMatchOptions plainProjection() {
  ProjectionMatchOptions options;
  options.check_orientation = false;
  options.ratio = 0.8;
  return options;
}

TEST(ProjectionMatcherTest, RatioWithinOctaveIgnoresTheSameCornerAtAnotherLevel) {
  // Distances to the all-zero query (bits): train 0 at octave 0 and train 1 at octave 1 (the
  // corner again, one level up) 32 each, train 2 at octave 0 128.
  const ProjectionCase c(0, {{1.0, 0, 0x01}, {2.0, 1, 0x01}, {3.0, 0, 0x0f}});
  ProjectionMatchOptions options = plainProjection();
  EXPECT_EQ(c.match(options), -1) << "32 >= 0.8 * 32: ambiguous across octaves";
  options.ratio_within_octave = true;
  EXPECT_EQ(c.match(options), 0) << "32 < 0.8 * 128 against octave 0's second best";
  // An equally close second at the best's own octave still rejects the match.
  const ProjectionCase same(0, {{1.0, 0, 0x01}, {2.0, 0, 0x01}});
  EXPECT_EQ(same.match(options), -1);
}

TEST(ProjectionMatcherTest, RadiusGrowsWithTheQueryOctave) {
  // The only candidate lies 10 px away; the query is at octave 2.
  const ProjectionCase c(2, {{10.0, 2, 0x00}});
  ProjectionMatchOptions options = plainProjection();
  options.radius_px = 8.0;
  EXPECT_EQ(c.match(options), -1);
  options.radius_octave_scale = 1.2;  // 8 * 1.44 = 11.5 px
  EXPECT_EQ(c.match(options), 0);
  options.radius_octave_scale = 0.9;
  EXPECT_THROW(c.match(options), OptionError);
}

TEST(ProjectionMatcherTest, OctaveWindowIsRelativeToTheQueryOctave) {
  const ProjectionCase c(3, {{1.0, 1, 0x00}, {2.0, 2, 0x00}, {3.0, 3, 0x00}, {4.0, 4, 0x00}});
  ProjectionMatchOptions options = plainProjection();
  options.ratio = 1.0;
  options.min_octave_offset = 1;  // only octave 4
  options.max_octave_offset = 1;
  EXPECT_EQ(c.match(options), 3);
  options.min_octave_offset = -1;  // ORB-SLAM's window: octaves 2 and 3, ties to the lower index
  options.max_octave_offset = 0;
  EXPECT_EQ(c.match(options), 1);
  options.min_octave_offset = 2;
  EXPECT_THROW(c.match(options), OptionError);
  options.min_octave_offset = -1;
  options.max_octave_offset = std::numeric_limits<int>::max();  // would overflow octave + offset
  EXPECT_THROW(c.match(options), OptionError);
}

TEST(ProjectionMatcherTest, FindsTheKeypointsNearTheirPredictedPositions) {
  // The second image is the first shifted by (12, -7) px; predictions carry 2 px of error.
  const cv::Mat big = test::texturedImage(800, 520, 4);
  const cv::Mat first = big(cv::Rect(20, 20, 752, 480)).clone();
  const cv::Mat second = big(cv::Rect(8, 27, 752, 480)).clone();
  const Eigen::Vector2d shift(12.0, -7.0);
  OrbExtractor extractor;
  const FeatureSet a = extractor.extract(first);
  const FeatureSet b = extractor.extract(second);
  const KeypointGrid grid(b.keypoints, b.image_size);
  std::vector<Eigen::Vector2d> predicted;
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 1.5);
  for (std::size_t i = 0; i < a.size(); ++i) {
    predicted.push_back(i % 10 == 9 ? Eigen::Vector2d::Constant(std::nan(""))
                                    : Eigen::Vector2d(a.keypoints[i].pixel + shift +
                                                      Eigen::Vector2d(noise(rng), noise(rng))));
  }
  ProjectionMatchOptions options;
  options.radius_px = 8.0;
  options.min_octave_offset = -1;
  options.max_octave_offset = 1;
  const std::vector<Match> matches = matchByProjection(a, predicted, b, grid, options);
  int correct = 0;
  std::vector<int> used(b.size(), 0);
  for (const Match& m : matches) {
    EXPECT_NE(m.query % 10, 9) << "no prediction, no match";
    EXPECT_EQ(++used[static_cast<std::size_t>(m.train)], 1);
    const Eigen::Vector2d error = b.keypoints[static_cast<std::size_t>(m.train)].pixel -
                                  a.keypoints[static_cast<std::size_t>(m.query)].pixel - shift;
    correct +=
        error.norm() < 1.5 * std::pow(1.2, a.keypoints[static_cast<std::size_t>(m.query)].octave);
  }
  // Keypoints that have a counterpart in the shifted image (the quadtree picks differently).
  int repeatable = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double tol = 1.5 * std::pow(1.2, a.keypoints[i].octave);
    repeatable += !grid.within(a.keypoints[i].pixel + shift, tol, a.keypoints[i].octave - 1,
                               a.keypoints[i].octave + 1)
                       .empty();
  }
  std::cout << "projection search: " << matches.size() << " matches of " << a.size()
            << " keypoints (" << repeatable << " repeated in the shifted image), "
            << 100.0 * correct / static_cast<double>(matches.size()) << " % at the true position\n";
  EXPECT_GT(static_cast<double>(matches.size()), 0.6 * repeatable);
  EXPECT_GT(repeatable, 600);
  EXPECT_GT(correct, 0.95 * static_cast<double>(matches.size()));
  EXPECT_THROW(matchByProjection(a, {}, b, grid), InputError);
}

}  // namespace
}  // namespace superdyna::features

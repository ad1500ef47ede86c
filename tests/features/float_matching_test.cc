// Float-descriptor (learned features) and class-wise paths of the matchers.

#include <gtest/gtest.h>

#include <cmath>

#include "superdyna/core/error.h"
#include "superdyna/features/matcher.h"
#include "superdyna/features/stereo_matcher.h"
#include "support/test_support.h"

namespace superdyna::features {
namespace {

constexpr int kLength = 64;

/// `n` random unit-norm rows (seeded).
cv::Mat unitRows(int n, std::uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat rows(n, kLength, CV_32FC1);
  rng.fill(rows, cv::RNG::NORMAL, 0.0, 1.0);
  for (int i = 0; i < n; ++i)
    cv::normalize(rows.row(i), rows.row(i));
  return rows;
}

/// The rows with Gaussian noise of `sigma` per element, renormalised.
cv::Mat perturbed(const cv::Mat& rows, double sigma, std::uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat noise(rows.size(), CV_32FC1);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, sigma);
  cv::Mat out = rows + noise;
  for (int i = 0; i < out.rows; ++i)
    cv::normalize(out.row(i), out.row(i));
  return out;
}

FeatureSet floatSet(const cv::Mat& descriptors, const std::vector<Eigen::Vector2d>& pixels) {
  FeatureSet set;
  set.descriptor_type = DescriptorType::kFloat;
  set.descriptors = descriptors;
  set.image_size = cv::Size(640, 480);
  for (const Eigen::Vector2d& p : pixels) {
    Keypoint k;
    k.pixel = p;  // learned keypoints: no angle (-1), octave 0
    set.keypoints.push_back(k);
  }
  return set;
}

std::vector<Eigen::Vector2d> gridPixels(int n) {
  std::vector<Eigen::Vector2d> pixels;
  for (int i = 0; i < n; ++i)
    pixels.emplace_back(20.0 + 50.0 * (i % 12), 20.0 + 50.0 * (i / 12));
  return pixels;
}

TEST(FloatMatching, DistancesAreEuclideanForFloatAndHammingForBinary) {
  const cv::Mat a = (cv::Mat_<float>(1, 3) << 1.0f, 0.0f, 0.0f);
  const cv::Mat b = (cv::Mat_<float>(1, 3) << 0.0f, 1.0f, 0.0f);
  EXPECT_NEAR(descriptorDistance(a, b), std::sqrt(2.0), 1e-6);
  const cv::Mat x = (cv::Mat_<std::uint8_t>(1, 2) << 0b1011, 0xFF);
  const cv::Mat y = (cv::Mat_<std::uint8_t>(1, 2) << 0b0001, 0x0F);
  EXPECT_EQ(descriptorDistance(x, y), 6.0);
  EXPECT_THROW(descriptorDistance(a, x), InputError);

  FeatureSet binary;
  binary.descriptors = cv::Mat(1, 32, CV_8UC1, cv::Scalar(0));
  binary.keypoints.resize(1);
  const FeatureSet learned = floatSet(unitRows(1, 1), gridPixels(1));
  test::expectError([&] { DescriptorMetric(binary, learned, "who"); },
                    {"who", "descriptor types differ"});
  EXPECT_FALSE(hasOrientation(learned));
  binary.keypoints[0].angle = 10.0f;
  EXPECT_TRUE(hasOrientation(binary));
}

TEST(FloatMatching, BruteForceFindsTheNoisyCopies) {
  const cv::Mat train_rows = unitRows(60, 2);
  // Query i is a noisy copy of train row (i * 7) % 60.
  cv::Mat query_rows(60, kLength, CV_32FC1);
  for (int i = 0; i < 60; ++i)
    train_rows.row((i * 7) % 60).copyTo(query_rows.row(i));
  query_rows = perturbed(query_rows, 0.03, 3);
  const FeatureSet query = floatSet(query_rows, gridPixels(60));
  const FeatureSet train = floatSet(train_rows, gridPixels(60));
  const std::vector<Match> matches = matchBruteForce(query, train);
  ASSERT_EQ(matches.size(), 60u);
  for (const Match& m : matches) {
    EXPECT_EQ(m.train, (m.query * 7) % 60);
    EXPECT_NEAR(m.distance, cv::norm(query_rows.row(m.query), train_rows.row(m.train)), 1e-5);
    EXPECT_LT(m.distance, 0.5);
  }
  BruteForceMatchOptions strict;
  strict.max_l2_distance = 0.01;  // below every noisy copy's distance
  EXPECT_TRUE(matchBruteForce(query, train, strict).empty());
}

TEST(FloatMatching, ClassWiseBruteForceNeverPairsDifferentClasses) {
  const cv::Mat rows = unitRows(24, 4);
  FeatureSet query = floatSet(perturbed(rows, 0.03, 5), gridPixels(24));
  FeatureSet train = floatSet(rows, gridPixels(24));
  for (int i = 0; i < 24; ++i) {
    query.keypoints[static_cast<std::size_t>(i)].class_id = i % 3;
    // The true partners of queries 0..5 lie on another class.
    train.keypoints[static_cast<std::size_t>(i)].class_id = i < 6 ? (i + 1) % 3 : i % 3;
  }
  BruteForceMatchOptions options;
  EXPECT_EQ(matchBruteForce(query, train, options).size(), 24u);  // class-blind: all 24
  options.same_class_only = true;
  const std::vector<Match> matches = matchBruteForce(query, train, options);
  EXPECT_EQ(matches.size(), 18u);
  for (const Match& m : matches) {
    EXPECT_EQ(m.query, m.train);
    EXPECT_EQ(query.keypoints[static_cast<std::size_t>(m.query)].class_id,
              train.keypoints[static_cast<std::size_t>(m.train)].class_id);
  }
}

TEST(FloatMatching, ProjectionMatchesWithoutAnglesAndRespectsClasses) {
  const cv::Mat rows = unitRows(48, 6);
  const std::vector<Eigen::Vector2d> pixels = gridPixels(48);
  FeatureSet train = floatSet(rows, pixels);
  FeatureSet query = floatSet(perturbed(rows, 0.03, 7), pixels);
  std::vector<Eigen::Vector2d> predicted;
  for (const Eigen::Vector2d& p : pixels)
    predicted.push_back(p + Eigen::Vector2d(3.0, -2.0));  // a prediction error of 3.6 px
  const KeypointGrid grid(train.keypoints, train.image_size);
  ProjectionMatchOptions options;  // check_orientation is on: skipped, keypoints have no angle
  ASSERT_TRUE(options.check_orientation);
  std::vector<Match> matches = matchByProjection(query, predicted, train, grid, options);
  ASSERT_EQ(matches.size(), 48u);
  for (const Match& m : matches)
    EXPECT_EQ(m.query, m.train);

  for (int i = 0; i < 48; i += 4)
    train.keypoints[static_cast<std::size_t>(i)].class_id = kClassVehicle;
  EXPECT_EQ(matchByProjection(query, predicted, train, grid, options).size(), 48u);
  options.same_class_only = true;
  matches = matchByProjection(query, predicted, train, grid, options);
  EXPECT_EQ(matches.size(), 36u);
  for (const Match& m : matches)
    EXPECT_NE(m.query % 4, 0);
}

/// A pinhole stereo rig: cam1 12 cm to the right of cam0.
std::pair<sensors::CameraCalibration, sensors::CameraCalibration> pinholeRig() {
  sensors::CameraCalibration cam0;
  cam0.name = "cam0";
  cam0.width = 640;
  cam0.height = 480;
  cam0.rate_hz = 20.0;
  cam0.fx = cam0.fy = 450.0;
  cam0.cx = 320.0;
  cam0.cy = 240.0;
  sensors::CameraCalibration cam1 = cam0;
  cam1.name = "cam1";
  cam1.T_b_c = cam0.T_b_c * SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.12, 0, 0));
  return {cam0, cam1};
}

TEST(FloatMatching, StereoMatcherTriangulatesFloatMatchesWithinClass) {
  const auto [cam0, cam1] = pinholeRig();
  const CameraModel left_camera = cam0.cameraModel(), right_camera = cam1.cameraModel();
  const SE3d T_c1_c0 = cam1.T_b_c.inverse() * cam0.T_b_c;
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> left_pixels, right_pixels;
  for (int i = 0; i < 40; ++i) {
    const Eigen::Vector3d p(-1.5 + 0.075 * i, -0.8 + 0.04 * (i % 9), 2.0 + 0.1 * (i % 13));
    points.push_back(p);
    left_pixels.push_back(*left_camera.project(p));
    right_pixels.push_back(*right_camera.project(T_c1_c0 * p));
  }
  const cv::Mat rows = unitRows(40, 8);
  FeatureSet left = floatSet(perturbed(rows, 0.03, 9), left_pixels);
  FeatureSet right = floatSet(rows, right_pixels);
  StereoMatchOptions options;
  const StereoMatcher matcher(cam0, cam1, options);
  const std::vector<StereoMatch> matches = matcher.match(left, right);
  ASSERT_EQ(matches.size(), 40u);
  for (const StereoMatch& m : matches) {
    EXPECT_EQ(m.left, m.right);
    EXPECT_NEAR((m.p_c0 - points[static_cast<std::size_t>(m.left)]).norm(), 0.0, 1e-6);
    EXPECT_NEAR(m.distance, cv::norm(left.descriptors.row(m.left), rows.row(m.right)), 1e-5);
  }

  for (int i = 0; i < 10; ++i)
    right.keypoints[static_cast<std::size_t>(i)].class_id = kClassPedestrian;
  options.same_class_only = true;
  const std::vector<StereoMatch> within = StereoMatcher(cam0, cam1, options).match(left, right);
  EXPECT_EQ(within.size(), 30u);
  for (const StereoMatch& m : within)
    EXPECT_GE(m.left, 10);
}

}  // namespace
}  // namespace superdyna::features

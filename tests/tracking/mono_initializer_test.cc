#include "superdyna/tracking/mono_initializer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <iostream>
#include <optional>
#include <random>

#include "support/test_support.h"

namespace superdyna::tracking {
namespace {

constexpr double kFocalPx = 450.0;

double degrees(double radians) {
  return radians * 180.0 / M_PI;
}

/// Projects world points (= view-0 camera frame) into both views with Gaussian pixel noise.
TwoViewMatches project(const std::vector<Eigen::Vector3d>& points, const SE3d& T_c0_c1,
                       double noise_px, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_px / kFocalPx);
  const SE3d T_c1_c0 = T_c0_c1.inverse();
  TwoViewMatches m;
  for (const Eigen::Vector3d& p0 : points) {
    const Eigen::Vector3d p1 = T_c1_c0 * p0;
    m.x0.emplace_back(p0.x() / p0.z() + noise(rng), p0.y() / p0.z() + noise(rng));
    m.x1.emplace_back(p1.x() / p1.z() + noise(rng), p1.y() / p1.z() + noise(rng));
    m.octave0.push_back(0);
    m.octave1.push_back(0);
  }
  return m;
}

/// Points in front of view 0 within the field of view, depths in [2, 6] m.
std::vector<Eigen::Vector3d> scenePoints(int n, unsigned seed, bool planar) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> xy(-0.6, 0.6), depth(2.0, 6.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) {
    const double z = planar ? 4.0 + 0.3 * points.size() / n : depth(rng);  // a slanted plane
    points.emplace_back(xy(rng) * z, xy(rng) * z * 0.7, z);
  }
  return points;
}

SE3d sidewaysMotion() {
  const Eigen::Matrix3d R = expSO3(Eigen::Vector3d(0.02, -0.08, 0.01));
  return SE3d(R, Eigen::Vector3d(0.35, 0.05, 0.1));
}

void expectRecovers(const TwoViewResult& r, const SE3d& truth,
                    const std::vector<Eigen::Vector3d>& points) {
  ASSERT_TRUE(r.ok) << r.failure;
  const double rotation_error =
      degrees(rotationAngle(r.T_c0_c1.rotation().transpose() * truth.rotation()));
  const double direction_error =
      degrees(std::acos(std::clamp(r.T_c0_c1.t.normalized().dot(truth.t.normalized()), -1.0, 1.0)));
  // Half-pixel noise and no bundle adjustment yet (the tracker runs one on the new map): the
  // rotation / translation-direction ambiguity of a sideways motion leaves errors of this order.
  EXPECT_LT(rotation_error, 1.0);
  EXPECT_LT(direction_error, 5.0);
  EXPECT_GT(r.good, static_cast<int>(0.9 * points.size()));
  // Points agree with the truth up to the common scale (median depth 1).
  const double scale = truth.t.norm() / r.T_c0_c1.t.norm();
  int close = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (r.points_c0[i] && (scale * *r.points_c0[i] - points[i]).norm() < 0.15 * points[i].z()) {
      ++close;
    }
  }
  EXPECT_GT(close, static_cast<int>(0.85 * points.size()));
}

TEST(MonoInitializer, RecoversMotionOfAGeneralScene) {
  const std::vector<Eigen::Vector3d> points = scenePoints(300, 1, false);
  const SE3d truth = sidewaysMotion();
  const TwoViewResult r = reconstructTwoView(project(points, truth, 0.5, 2), kFocalPx, {});
  expectRecovers(r, truth, points);
  EXPECT_FALSE(r.from_homography);
}

TEST(MonoInitializer, RecoversMotionOfAPlanarScene) {
  const std::vector<Eigen::Vector3d> points = scenePoints(300, 3, true);
  const SE3d truth = sidewaysMotion();
  expectRecovers(reconstructTwoView(project(points, truth, 0.5, 4), kFocalPx, {}), truth, points);
}

TEST(MonoInitializer, MedianDepthIsOne) {
  const std::vector<Eigen::Vector3d> points = scenePoints(200, 5, false);
  const TwoViewResult r =
      reconstructTwoView(project(points, sidewaysMotion(), 0.3, 6), kFocalPx, {});
  ASSERT_TRUE(r.ok) << r.failure;
  std::vector<double> depths;
  for (const auto& p : r.points_c0)
    if (p) depths.push_back(p->z());
  std::sort(depths.begin(), depths.end());
  EXPECT_NEAR(depths[depths.size() / 2], 1.0, 1e-9);
}

TEST(MonoInitializer, FailsCleanlyWithoutParallax) {
  const std::vector<Eigen::Vector3d> points = scenePoints(300, 7, false);
  // Pure rotation: no translation, hence no depth.
  const SE3d rotation(expSO3(Eigen::Vector3d(0.0, 0.1, 0.02)), Eigen::Vector3d::Zero());
  const TwoViewResult r = reconstructTwoView(project(points, rotation, 0.5, 8), kFocalPx, {});
  EXPECT_FALSE(r.ok);
  EXPECT_FALSE(r.failure.empty());
  // A tiny translation against 2-6 m depths gives too little parallax.
  const SE3d creep(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.01, 0.0, 0.0));
  const TwoViewResult c = reconstructTwoView(project(points, creep, 0.5, 9), kFocalPx, {});
  EXPECT_FALSE(c.ok);
}

TEST(MonoInitializer, TooFewMatchesFail) {
  const std::vector<Eigen::Vector3d> points = scenePoints(50, 10, false);
  const TwoViewResult r =
      reconstructTwoView(project(points, sidewaysMotion(), 0.5, 11), kFocalPx, {});
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.failure, "too few matches");
}

/// A frame seeing `points` (camera frame of view 0) from pose T_c0_c: ORB-like keypoints at their
/// exact pixels, one random descriptor per point (the same in every view), class_id by class_of.
Frame viewOf(const std::vector<Eigen::Vector3d>& points, const SE3d& T_c0_c, TimeNs t_ns,
             const std::function<int(std::size_t)>& class_of) {
  std::mt19937 rng(17);  // the same descriptors in every view
  std::uniform_int_distribution<int> byte(0, 255);
  Frame frame;
  frame.t_ns = t_ns;
  frame.features.image_size = cv::Size(752, 480);
  frame.features.descriptors = cv::Mat(static_cast<int>(points.size()), 32, CV_8UC1);
  const SE3d T_c_c0 = T_c0_c.inverse();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d p_c = T_c_c0 * points[i];
    const Eigen::Vector2d x = p_c.head<2>() / p_c.z();
    features::Keypoint k;
    k.pixel = kFocalPx * x + Eigen::Vector2d(376.0, 240.0);
    k.angle = 0.0f;
    k.class_id = class_of(i);
    frame.features.keypoints.push_back(k);
    frame.normalized.push_back(x);
    for (int c = 0; c < 32; ++c) {
      frame.features.descriptors.at<std::uint8_t>(static_cast<int>(i), c) =
          static_cast<std::uint8_t>(byte(rng));
    }
  }
  return frame;
}

/// Initialisation points whose reference and current keypoints carry different class_id.
int crossClassPoints(const MonoInitialization& init, const Frame& current) {
  int cross = 0;
  for (const MonoInitialization::Point& p : init.points) {
    const auto r = static_cast<std::size_t>(p.reference_index);
    const auto c = static_cast<std::size_t>(p.current_index);
    if (init.reference.features.keypoints[r].class_id != current.features.keypoints[c].class_id) {
      ++cross;
    }
  }
  return cross;
}

TEST(MonoInitializer, ClassWiseMatchingRefusesCrossClassPairs) {
  const std::vector<Eigen::Vector3d> points = scenePoints(400, 12, false);
  const SE3d motion(expSO3(Eigen::Vector3d(0.0, -0.02, 0.0)), Eigen::Vector3d(0.25, 0.03, 0.05));
  const Frame reference =
      viewOf(points, SE3d(), 0, [](std::size_t) { return features::kClassBackground; });
  // In the current view every third point lies on a vehicle: the reference saw it as background.
  const Frame current = viewOf(points, motion, secondsToNs(0.2), [](std::size_t i) {
    return i % 3 == 0 ? features::kClassVehicle : features::kClassBackground;
  });
  for (const bool class_wise : {false, true}) {
    MonoInitializerOptions options;
    options.same_class_only = class_wise;
    MonoInitializer initializer(options, kFocalPx);
    EXPECT_FALSE(initializer.addFrame(reference));
    const std::optional<MonoInitialization> init = initializer.addFrame(current);
    ASSERT_TRUE(init) << initializer.lastFailure();
    const int cross = crossClassPoints(*init, current);
    std::cout << "mono initialisation, class-wise " << (class_wise ? "on" : "off") << ": "
              << init->points.size() << " points, " << cross << " cross-class\n";
    if (class_wise) {
      EXPECT_EQ(cross, 0);
      EXPECT_GT(init->points.size(), 200u);  // the 2 in 3 background points remain
    } else {
      EXPECT_GT(cross, 100);
    }
  }
}

TEST(MonoInitializer, RefusesARotationTheGyroscopeContradicts) {
  const std::vector<Eigen::Vector3d> points = scenePoints(400, 21, false);
  const SE3d motion(expSO3(Eigen::Vector3d(0.0, -0.02, 0.0)), Eigen::Vector3d(0.25, 0.03, 0.05));
  const auto background = [](std::size_t) { return features::kClassBackground; };
  const Frame reference = viewOf(points, SE3d(), 0, background);
  const Frame current = viewOf(points, motion, secondsToNs(0.1), background);
  // 0.1 s apart: up to 0.5 + 5 * 0.1 = 1 deg from the gyroscope's rotation is accepted.
  const Eigen::Matrix3d off = motion.rotation() * expSO3(Eigen::Vector3d(0.0, 0.0, 0.03));
  MonoInitializer initializer({}, kFocalPx);
  EXPECT_FALSE(initializer.addFrame(reference));
  EXPECT_FALSE(initializer.addFrame(current, off));  // 1.7 deg off
  EXPECT_EQ(initializer.lastFailure(), "rotation disagrees with the gyroscope");
  ASSERT_TRUE(initializer.hasReference());  // kept for the next frame
  EXPECT_EQ(initializer.referenceTime(), 0);
  const std::optional<MonoInitialization> init = initializer.addFrame(current, motion.rotation());
  ASSERT_TRUE(init) << initializer.lastFailure();
  EXPECT_LT(degrees(rotationAngle(init->T_c0_c1.rotation().transpose() * motion.rotation())), 0.5);
  EXPECT_GT(init->points.size(), 300u);
}

TEST(MonoInitializer, RejectsBadOptions) {
  MonoInitializerOptions options;
  options.min_parallax_deg = 0.0;
  test::expectError<OptionError>([&] { options.validate(); }, {"mono_init.min_parallax_deg"});
  options = {};
  options.max_gyro_rotation_error_deg = -1.0;
  test::expectError<OptionError>([&] { options.validate(); },
                                 {"mono_init.max_gyro_rotation_error_deg"});
  options = {};
  options.ratio = 1.5;
  test::expectError<OptionError>([&] { MonoInitializer(options, kFocalPx); }, {"mono_init.ratio"});
}

}  // namespace
}  // namespace superdyna::tracking

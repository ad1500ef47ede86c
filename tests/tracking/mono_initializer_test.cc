#include "superdyna/tracking/mono_initializer.h"

#include <gtest/gtest.h>

#include <cmath>
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

TEST(MonoInitializer, RejectsBadOptions) {
  MonoInitializerOptions options;
  options.min_parallax_deg = 0.0;
  test::expectError<OptionError>([&] { options.validate(); }, {"mono_init.min_parallax_deg"});
  options = {};
  options.ratio = 1.5;
  test::expectError<OptionError>([&] { MonoInitializer(options, kFocalPx); }, {"mono_init.ratio"});
}

}  // namespace
}  // namespace superdyna::tracking

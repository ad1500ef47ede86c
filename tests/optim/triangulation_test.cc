#include "superdyna/optim/triangulation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "superdyna/core/error.h"

namespace superdyna::optim {
namespace {

/// Two cameras 0.3..1 m apart looking roughly the same way, a point 1..8 m in front of both,
/// with at least ~2.5 degrees of parallax.
struct TwoViews {
  SE3d T_w_c1, T_w_c2;
  Eigen::Vector3d p_w;
  Eigen::Vector3d p_c1, p_c2;
};

TwoViews randomTwoViews(std::mt19937& rng, const Eigen::Vector3d& offset_w) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const auto vector = [&]() -> Eigen::Vector3d {
    return Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
  };
  for (;;) {
    TwoViews v;
    v.T_w_c1 = SE3d(expSO3(M_PI * vector()), offset_w + vector());
    const Eigen::Vector3d baseline_c1 = vector().normalized() * (0.3 + 0.35 * (1.0 + unit(rng)));
    v.T_w_c2 = v.T_w_c1 * SE3d(expSO3(0.2 * vector()), baseline_c1);
    v.p_c1 = Eigen::Vector3d(unit(rng), unit(rng), 4.5 + 3.5 * unit(rng));
    v.p_w = v.T_w_c1 * v.p_c1;
    v.p_c2 = v.T_w_c2.inverse() * v.p_w;
    const double cos_parallax =
        cosParallax(v.p_c1, v.T_w_c1, v.p_c2, v.T_w_c2);  // rays towards the point
    if (v.p_c2.z() > 0.5 && cos_parallax < 0.999) return v;
  }
}

Eigen::Vector3d normalizedBearing(const Eigen::Vector3d& p_c) {
  return p_c / p_c.z();  // (x, y, 1)
}

TEST(TriangulationTest, NoiselessBearingsGiveThePointBack) {
  std::mt19937 rng(1);
  double worst_error_m = 0.0;
  for (const Eigen::Vector3d& offset_w :
       {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1000.0, -2000.0, 50.0)}) {
    for (int trial = 0; trial < 200; ++trial) {
      const TwoViews v = randomTwoViews(rng, offset_w);
      // Normalised coordinates (x, y, 1) for the first view, unit bearings for the second.
      const TriangulationResult result =
          triangulateTwoView(normalizedBearing(v.p_c1), v.T_w_c1, v.p_c2.normalized(), v.T_w_c2);
      ASSERT_TRUE(result.ok()) << toString(result.status) << " trial " << trial;
      worst_error_m = std::max(worst_error_m, (result.p_w - v.p_w).norm());
    }
  }
  std::printf("worst triangulation error over 400 noiseless cases: %.3g m\n", worst_error_m);
  EXPECT_LT(worst_error_m, 1e-9);
}

TEST(TriangulationTest, RaysBeyondNinetyDegreesWork) {
  // A fisheye-like bearing with z < 0 in the first camera.
  const SE3d T_w_c1;
  const SE3d T_w_c2(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.0, 1.0, 0.0));
  const Eigen::Vector3d p_w(4.0, 0.5, -1.0);
  const TriangulationResult result =
      triangulateTwoView(p_w.normalized(), T_w_c1, (p_w - T_w_c2.t).normalized(), T_w_c2);
  ASSERT_TRUE(result.ok());
  EXPECT_LT((result.p_w - p_w).norm(), 1e-9);
}

TEST(TriangulationTest, RejectsLowParallax) {
  // 10 cm baseline, point 100 m away: rays 0.057 deg apart.
  const SE3d T_w_c1;
  const SE3d T_w_c2(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.1, 0.0, 0.0));
  const Eigen::Vector3d p_w(0.5, 0.2, 100.0);
  const TriangulationResult far = triangulateTwoView(p_w, T_w_c1, p_w - T_w_c2.t, T_w_c2);
  EXPECT_EQ(far.status, TriangulationStatus::kLowParallax);
  EXPECT_GT(far.cos_parallax, 0.9998);
  // Pure rotation: the same ray from the same centre.
  const SE3d rotated(expSO3(Eigen::Vector3d(0.0, 0.3, 0.0)), Eigen::Vector3d::Zero());
  const Eigen::Vector3d p_c2 = rotated.inverse() * p_w;
  EXPECT_EQ(triangulateTwoView(p_w, T_w_c1, p_c2, rotated).status,
            TriangulationStatus::kLowParallax);
  // The same point 2 m away has enough parallax (2.9 deg).
  const Eigen::Vector3d near_w(0.5, 0.2, 2.0);
  EXPECT_TRUE(triangulateTwoView(near_w, T_w_c1, near_w - T_w_c2.t, T_w_c2).ok());
  // A stricter threshold rejects it.
  TriangulationOptions strict;
  strict.max_cos_parallax = std::cos(5.0 * M_PI / 180.0);
  EXPECT_EQ(triangulateTwoView(near_w, T_w_c1, near_w - T_w_c2.t, T_w_c2, strict).status,
            TriangulationStatus::kLowParallax);
}

TEST(TriangulationTest, RejectsPointsBehindEitherCamera) {
  std::mt19937 rng(2);
  for (int trial = 0; trial < 50; ++trial) {
    const TwoViews v = randomTwoViews(rng, Eigen::Vector3d::Zero());
    // The rays meet behind both cameras.
    EXPECT_EQ(triangulateTwoView(-v.p_c1, v.T_w_c1, -v.p_c2, v.T_w_c2).status,
              TriangulationStatus::kBehindCamera);
    // In front of the first camera, behind the second.
    EXPECT_EQ(triangulateTwoView(v.p_c1, v.T_w_c1, -v.p_c2, v.T_w_c2).status,
              TriangulationStatus::kBehindCamera);
  }
  // A minimum depth: the point 4.5 m away is rejected when 5 m are required.
  const SE3d T_w_c2(Eigen::Matrix3d::Identity(), Eigen::Vector3d(1.0, 0.0, 0.0));
  const Eigen::Vector3d p_w(0.0, 0.0, 4.5);
  TriangulationOptions options;
  options.min_depth_m = 5.0;
  EXPECT_TRUE(triangulateTwoView(p_w, SE3d(), p_w - T_w_c2.t, T_w_c2).ok());
  EXPECT_EQ(triangulateTwoView(p_w, SE3d(), p_w - T_w_c2.t, T_w_c2, options).status,
            TriangulationStatus::kBehindCamera);
}

TEST(TriangulationTest, DegenerateInputsAndOptions) {
  const SE3d T_w_c2(Eigen::Matrix3d::Identity(), Eigen::Vector3d(1.0, 0.0, 0.0));
  EXPECT_EQ(
      triangulateTwoView(Eigen::Vector3d::Zero(), SE3d(), Eigen::Vector3d(0, 0, 1), T_w_c2).status,
      TriangulationStatus::kDegenerate);
  TriangulationOptions options;
  options.max_cos_parallax = 1.5;
  EXPECT_THROW(options.validate(), OptionError);
  options = {};
  options.min_depth_m = -1.0;
  EXPECT_THROW(options.validate(), OptionError);
}

TEST(TriangulationTest, StereoDepthGivesThePoint) {
  const SE3d T_w_c(expSO3(Eigen::Vector3d(0.1, -0.4, 0.2)), Eigen::Vector3d(3.0, -1.0, 2.0));
  const Eigen::Vector3d p_c(0.7, -0.3, 6.0);
  const double baseline_m = 0.11;
  const double x_left = p_c.x() / p_c.z();
  const double x_right = (p_c.x() - baseline_m) / p_c.z();
  const std::optional<double> depth = depthFromRectifiedStereo(x_left, x_right, baseline_m);
  ASSERT_TRUE(depth.has_value());
  EXPECT_NEAR(*depth, 6.0, 1e-12);
  const std::optional<Eigen::Vector3d> p_w = pointFromDepth(p_c.head<2>() / p_c.z(), *depth, T_w_c);
  ASSERT_TRUE(p_w.has_value());
  EXPECT_LT((*p_w - T_w_c * p_c).norm(), 1e-12);

  EXPECT_FALSE(depthFromRectifiedStereo(0.1, 0.1, baseline_m).has_value());  // zero disparity
  EXPECT_FALSE(depthFromRectifiedStereo(0.1, 0.2, baseline_m).has_value());  // negative
  EXPECT_FALSE(pointFromDepth(Eigen::Vector2d::Zero(), -1.0, T_w_c).has_value());
  EXPECT_FALSE(pointFromDepth(Eigen::Vector2d::Zero(), 0.0, T_w_c).has_value());
}

}  // namespace
}  // namespace superdyna::optim

#include "superdyna/dynamic/motion_residual.h"

#include <gtest/gtest.h>

#include <cmath>

namespace superdyna::dynamic {
namespace {

constexpr double kFocal = 400.0;

Eigen::Vector2d normalizedOf(const Eigen::Vector3d& p) {
  return p.head<2>() / p.z();
}

/// The camera moves 0.5 m to its right and turns 2 degrees about y.
SE3d curFromPrev() {
  const SE3d T_prev_cur(Eigen::Quaterniond(Eigen::AngleAxisd(0.035, Eigen::Vector3d::UnitY())),
                        Eigen::Vector3d(0.5, 0.0, 0.0));
  return T_prev_cur.inverse();
}

TEST(MotionResidualTest, StaticPointHasZeroResidualUnderEveryTest) {
  const SE3d T = curFromPrev();
  const Eigen::Vector3d p_prev(1.0, -0.5, 8.0);
  const Eigen::Vector2d x_prev = normalizedOf(p_prev), x_cur = normalizedOf(T * p_prev);
  EXPECT_NEAR(*epipolarDistancePx(x_prev, x_cur, T, kFocal), 0.0, 1e-9);
  EXPECT_NEAR(*reprojectionDistancePx(p_prev, x_cur, T, kFocal), 0.0, 1e-9);
}

TEST(MotionResidualTest, EpipolarDistanceIsThePerpendicularOffsetInPixels) {
  // Pure sideways translation: epipolar lines are horizontal; a point that also moved down by
  // 0.1 m at 8 m depth is 400 * 0.1 / 8 = 5 px off its line.
  const SE3d T(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.5, 0.0, 0.0));
  const Eigen::Vector3d p_prev(1.0, -0.5, 8.0);
  const Eigen::Vector3d p_cur = T * (p_prev + Eigen::Vector3d(0.0, 0.1, 0.0));
  EXPECT_NEAR(*epipolarDistancePx(normalizedOf(p_prev), normalizedOf(p_cur), T, kFocal), 5.0, 1e-9);
}

TEST(MotionResidualTest, MotionAlongTheEpipolarLineIsSeenOnlyByReprojection) {
  // The point moves with the camera's own translation direction (a car driving beside it): it
  // stays on its epipolar line, but its stereo point no longer reprojects where it is seen.
  const SE3d T = curFromPrev();
  const Eigen::Vector3d p_prev(1.0, -0.5, 8.0);
  const Eigen::Vector3d moved = p_prev + Eigen::Vector3d(0.4, 0.0, 0.0);  // along T_prev_cur.t
  const Eigen::Vector2d x_prev = normalizedOf(p_prev), x_cur = normalizedOf(T * moved);
  EXPECT_LT(*epipolarDistancePx(x_prev, x_cur, T, kFocal), 1e-6);
  EXPECT_GT(*reprojectionDistancePx(p_prev, x_cur, T, kFocal), 15.0);
}

TEST(MotionResidualTest, TheRayTestSeesMotionAlongTheLineAgainstAStaticPointsFlow) {
  // The camera moves 0.5 m to its right: a static point's image moves left. A car beside it
  // driving 1.2 m to the right in the same time stays on its epipolar line but its image moves
  // right, which no depth in front of the camera explains.
  const SE3d T = curFromPrev();
  const Eigen::Vector3d p_prev(1.0, -0.5, 8.0);
  const Eigen::Vector2d x_prev = normalizedOf(p_prev);
  const Eigen::Vector2d x_overtaking = normalizedOf(T * (p_prev + Eigen::Vector3d(1.2, 0, 0)));
  EXPECT_LT(*epipolarDistancePx(x_prev, x_overtaking, T, kFocal), 1e-6);
  // Beyond the point at infinite depth by the car's extra 0.7 m at 8 m: about 35 px.
  EXPECT_NEAR(*epipolarRayDistancePx(x_prev, x_overtaking, T, kFocal), 35.0, 2.0);
  // Slower than the camera (0.4 m), its image moves left like a farther static point's: unseen.
  const Eigen::Vector2d x_slower = normalizedOf(T * (p_prev + Eigen::Vector3d(0.4, 0, 0)));
  EXPECT_LT(*epipolarRayDistancePx(x_prev, x_slower, T, kFocal), 1e-6);
  // Static points at any depth are on the reachable part; off the line it is the line distance.
  for (const double depth : {0.5, 3.0, 40.0, 1e4}) {
    const Eigen::Vector3d p = p_prev.normalized() * depth;
    EXPECT_LT(*epipolarRayDistancePx(normalizedOf(p), normalizedOf(T * p), T, kFocal), 1e-6);
  }
  const Eigen::Vector2d x_below = normalizedOf(T * (p_prev + Eigen::Vector3d(0, 0.1, 0)));
  EXPECT_NEAR(*epipolarRayDistancePx(x_prev, x_below, T, kFocal),
              *epipolarDistancePx(x_prev, x_below, T, kFocal), 1e-9);
}

TEST(MotionResidualTest, TheRayTestSeesAPointApproachingFasterThanTheCameraMovesBackward) {
  // Moving backward 0.5 m, a static point's image moves toward the epipole (depth 0) and stops
  // there; a point that crosses it came closer than the camera went.
  const SE3d T(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 0.0, 0.5));
  const Eigen::Vector3d p_prev(1.0, 0.0, 4.0);
  const Eigen::Vector2d x_prev = normalizedOf(p_prev);
  const Eigen::Vector2d x_static = normalizedOf(T * p_prev);
  EXPECT_LT(*epipolarRayDistancePx(x_prev, x_static, T, kFocal), 1e-9);
  // Beyond the epipole (the image centre) by 0.1 in normalised units: 40 px from its nearer end.
  EXPECT_NEAR(*epipolarRayDistancePx(x_prev, Eigen::Vector2d(-0.1, 0.0), T, kFocal), 40.0, 1e-6);
}

TEST(MotionResidualTest, RotationTransferIsExactForPureRotation) {
  const SE3d T(Eigen::Quaterniond(Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitX())),
               Eigen::Vector3d::Zero());
  const Eigen::Vector3d p_prev(0.3, 0.2, 3.0);
  const Eigen::Vector2d x_prev = normalizedOf(p_prev), x_cur = normalizedOf(T * p_prev);
  EXPECT_FALSE(epipolarDistancePx(x_prev, x_cur, T, kFocal).has_value());
  EXPECT_NEAR(*rotationTransferDistancePx(x_prev, x_cur, T, kFocal), 0.0, 1e-9);
  EXPECT_NEAR(*rotationTransferDistancePx(x_prev, x_cur + Eigen::Vector2d(0.01, 0.0), T, kFocal),
              4.0, 1e-9);
}

}  // namespace
}  // namespace superdyna::dynamic

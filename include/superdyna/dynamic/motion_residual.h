#pragma once
// How far a feature matched between two frames is from where a static point would be, given the
// predicted relative camera pose: the paper's epipolar distance (Eq. 7) and two tests that cover
// its blind spots.
//
// All residuals are in pixels: computed on undistorted normalised coordinates and multiplied by
// the focal length, so that lens distortion does not enter and one threshold serves the image.
//
// - Epipolar: distance of the current point to the epipolar line E x_prev (E = [t]x R of
//   T_cur_prev). Blind to motion along the epipolar line (a car driving parallel to the camera's
//   translation) and meaningless when the translation is near zero (E -> 0).
// - Reprojection (stereo): the previous frame's stereo point moved by T_cur_prev and projected;
//   sees motion in every image direction, at the cost of stereo depth noise (which grows with
//   depth squared; the background threshold of the same test absorbs it).
// - Rotation transfer: the previous bearing rotated by R only (the infinite-depth homography);
//   for near-zero translation, where a static point's image moves by the rotation alone.

#include <Eigen/Core>
#include <optional>

#include "superdyna/core/geometry.h"

namespace superdyna::dynamic {

enum class ResidualTest { kEpipolar, kReprojection, kRotationTransfer };
inline constexpr int kResidualTestCount = 3;
const char* toString(ResidualTest test);

/// Distance [px] of x_cur to the epipolar line of x_prev (normalised coordinates) under
/// T_cur_prev; `focal_px` converts normalised units to pixels. nullopt when the translation is
/// zero or the line is degenerate.
std::optional<double> epipolarDistancePx(const Eigen::Vector2d& x_prev,
                                         const Eigen::Vector2d& x_cur, const SE3d& T_cur_prev,
                                         double focal_px);

/// Distance [px] between x_cur and the projection of the previous frame's point p_prev (in the
/// previous camera frame [m]) moved by T_cur_prev; nullopt when it lands behind the camera.
std::optional<double> reprojectionDistancePx(const Eigen::Vector3d& p_prev,
                                             const Eigen::Vector2d& x_cur, const SE3d& T_cur_prev,
                                             double focal_px);

/// Distance [px] between x_cur and the previous bearing rotated by T_cur_prev's rotation only;
/// nullopt when it lands behind the camera.
std::optional<double> rotationTransferDistancePx(const Eigen::Vector2d& x_prev,
                                                 const Eigen::Vector2d& x_cur,
                                                 const SE3d& T_cur_prev, double focal_px);

}  // namespace superdyna::dynamic

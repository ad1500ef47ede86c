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
//   translation) and meaningless when the translation is near zero (E -> 0). The ray variant
//   also measures how far the point is beyond the line's reachable part (positive depth), which
//   sees such motion when it runs against a static point's flow.
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

/// Distance [px] of x_cur to the part of x_prev's epipolar line that a static point in front of
/// both cameras can reach: the image of depths (0, inf) of x_prev's ray, a half-line from the
/// point at infinite depth (the rotated bearing) away from the epipole when the camera moves
/// forward. On that part it is the epipolar distance; off it, the distance to the part's nearer
/// end. Sees the half of the motion along the epipolar line that runs against a static point's
/// flow (a car overtaking the camera, a person walking against it), which no static depth
/// explains. nullopt when epipolarDistancePx is.
std::optional<double> epipolarRayDistancePx(const Eigen::Vector2d& x_prev,
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

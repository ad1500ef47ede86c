#pragma once
// Landmark initialisation: two-view linear triangulation (DLT) and stereo depth.
//
// Observations are bearings in the camera frame: any non-zero direction towards the point, e.g.
// the undistorted normalised coordinates as (x, y, 1), or the unit vector of
// CameraModel::unproject (which also covers fisheye rays beyond 90 degrees).

#include <Eigen/Core>
#include <optional>
#include <string>

#include "superdyna/core/geometry.h"

namespace superdyna::optim {

struct TriangulationOptions {
  /// Rays whose angle has a larger cosine are rejected as too little parallax. Default 0.9998
  /// (about 1.15 degrees), as ORB-SLAM.
  double max_cos_parallax = 0.9998;
  /// The point must be farther than this [m] in front of each camera along its ray. Default 0: in
  /// front is enough.
  double min_depth_m = 0.0;

  /// Throws OptionError when max_cos_parallax is outside (-1, 1] or min_depth_m is negative.
  void validate() const;
};

enum class TriangulationStatus {
  kOk,
  kLowParallax,   ///< The rays are (nearly) parallel.
  kBehindCamera,  ///< The point is not in front of one of the cameras (cheirality).
  kDegenerate,    ///< A zero bearing, or the solution is at infinity or not finite.
};
std::string toString(TriangulationStatus status);

struct TriangulationResult {
  TriangulationStatus status = TriangulationStatus::kDegenerate;
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();  ///< The point [m]; valid when ok().
  double cos_parallax = 1.0;  ///< Cosine of the angle between the two rays in the world frame.

  bool ok() const { return status == TriangulationStatus::kOk; }
};

/// Cosine of the angle between two bearings after rotating them into the world frame.
double cosParallax(const Eigen::Vector3d& bearing_c1, const SE3d& T_w_c1,
                   const Eigen::Vector3d& bearing_c2, const SE3d& T_w_c2);

/// Triangulates the point seen along bearing_c1 from camera pose T_w_c1 and along bearing_c2 from
/// T_w_c2: the rays' parallax is checked first, then the homogeneous point X minimising
/// sum |b_i x (T_ci_c1 X)|^2 (|X| = 1, in camera 1's frame for conditioning) is taken from the SVD
/// of the stacked 6x4 system, and the point must lie in front of both cameras (distance along each
/// unit bearing > min_depth_m).
/// Validates the options (OptionError).
TriangulationResult triangulateTwoView(const Eigen::Vector3d& bearing_c1, const SE3d& T_w_c1,
                                       const Eigen::Vector3d& bearing_c2, const SE3d& T_w_c2,
                                       const TriangulationOptions& options = {});

/// The point at depth depth_m [m] (along the camera z axis) behind the normalised coordinates
/// (x, y) of a camera at T_w_c; nullopt when the depth is not positive and finite.
std::optional<Eigen::Vector3d> pointFromDepth(const Eigen::Vector2d& normalized, double depth_m,
                                              const SE3d& T_w_c);

/// Depth [m] of a rectified stereo match from its normalised x in the left and right cameras
/// (right camera at +baseline_m along x): baseline_m / (x_left - x_right); nullopt when the
/// disparity is not positive.
std::optional<double> depthFromRectifiedStereo(double x_left, double x_right, double baseline_m);

}  // namespace superdyna::optim

#pragma once
// The relative camera pose the moving-object test compares against, refined on the static
// background.
//
// The prediction (IMU preintegration or the motion model) is off by its velocity error: a
// translation error dt moves a static point's image by about f |dt| / z, so near objects (a
// parked car 3 m away) get residuals several times those of the far background that sets the
// threshold, and look as if they moved. With stereo, the background pairs' previous stereo points
// and current observations pin the relative pose down: a few Gauss-Newton steps of their
// reprojection error starting from the prediction (Huber-weighted, then without the points the
// pose cannot explain, so that mismatches and unlabelled movers do not pull it) remove that error
// before any object is tested.

#include <Eigen/Core>
#include <vector>

#include "superdyna/core/geometry.h"

namespace superdyna::dynamic {

struct MotionRefinementOptions {
  int min_points = 20;    ///< Fewer points: the prediction is returned unchanged, >= 6.
  int iterations = 5;     ///< Gauss-Newton steps, >= 1.
  double huber_px = 2.0;  ///< Huber threshold of the reprojection error [px], > 0.
  /// From the third step on, points with an error above reject_factor * huber_px are left out.
  double reject_factor = 4.0;
};

/// T_cur_prev refined so that the points p_prev (previous camera [m]) project onto the observed
/// normalised points x_cur (current camera); `focal_px` scales normalised errors to pixels.
SE3d refineRelativePose(const std::vector<Eigen::Vector3d>& p_prev,
                        const std::vector<Eigen::Vector2d>& x_cur, const SE3d& T_cur_prev,
                        double focal_px, const MotionRefinementOptions& options = {});

}  // namespace superdyna::dynamic

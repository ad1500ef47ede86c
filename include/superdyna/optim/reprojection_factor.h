#pragma once
// Reprojection residuals of a landmark p_w observed by a camera rigidly mounted on the body.
//
// Everything happens in the undistorted normalised image plane, so lens distortion stays out of
// the optimisation: the keypoint is undistorted once (CameraModel::undistort) to (x, y) = (X/Z,
// Y/Z), and the error against the pinhole projection of p_c = T_b_c^-1 T_w_b^-1 p_w is scaled by
// the focal lengths back to pixels and whitened by the keypoint's standard deviation:
//
//   mono:    r = [fx (x - X/Z); fy (y - Y/Z)] / sigma                                    (2 rows)
//   stereo:  r = [fx (x - X/Z); fy (y - Y/Z); fx (x_r - (X - b)/Z)] / sigma              (3 rows)
//
// with sigma = sigma0 * scale^octave [px] and, for a rectified stereo pair, x_r the normalised x of
// the match in the right camera, whose centre is at +b [m] along the left camera's x axis. For an
// unrectified pair, add a second (mono) ReprojectionFactor with the second camera's T_b_c.
// A consistent residual has unit covariance, so |r|^2 follows a chi^2 with 2 (mono) or 3
// (stereo) degrees of freedom; the usual robust loss is Huber with delta = sqrt(kChi2Mono95) or
// sqrt(kChi2Stereo95) (in these whitened units; equal to pixels at octave 0 with sigma0 = 1 px).
//
// Parameter blocks: the body pose T_w_b (7, see se3_manifold.h) and the point p_w (3, m). Analytic
// Jacobians. Evaluation fails (returns false, so Ceres rejects the step) when the point is not at
// least kMinProjectionDepthM in front of the camera.

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "superdyna/core/camera_model.h"
#include "superdyna/core/geometry.h"

namespace superdyna::optim {

inline constexpr double kChi2Mono95 = 5.991;          ///< 95 % quantile of chi^2 with 2 dof.
inline constexpr double kChi2Stereo95 = 7.815;        ///< 95 % quantile of chi^2 with 3 dof.
inline constexpr double kMinProjectionDepthM = 1e-6;  ///< Smallest camera depth Z evaluated [m].

/// Standard deviation [px] of a keypoint detected at `octave`: sigma0_px * scale_factor^octave.
double octaveSigmaPx(int octave, double sigma0_px = 1.0, double scale_factor = 1.2);

/// A new Huber loss with delta = sqrt(chi2_threshold), for whitened residuals. The caller (usually
/// the ceres::Problem it is passed to) owns it.
ceres::LossFunction* newHuberLoss(double chi2_threshold);

/// The observing camera as the reprojection factors need it.
struct ReprojectionCamera {
  SE3d T_b_c;               ///< Camera pose in the body frame (held constant).
  double fx = 1.0;          ///< Focal length along x [px]: scales normalised errors to pixels.
  double fy = 1.0;          ///< Focal length along y [px].
  double baseline_m = 0.0;  ///< Rectified stereo baseline [m]; 0 = no right camera.

  /// The focal lengths of `camera` (its distortion is irrelevant here).
  static ReprojectionCamera from(const CameraModel& camera, const SE3d& T_b_c,
                                 double baseline_m = 0.0);
  /// Throws OptionError when a focal length is not positive or the baseline is negative.
  void validate() const;
};

/// Distance between the first two cameras of a rig [m] (left camera first); 0 with one camera.
double stereoBaseline(const std::vector<ReprojectionCamera>& rig);

/// p_c = T_b_c^-1 T_w_b^-1 p_w.
Eigen::Vector3d worldToCamera(const SE3d& T_w_b, const SE3d& T_b_c, const Eigen::Vector3d& p_w);

/// Monocular observation (2 residuals). Parameter blocks: pose T_w_b (7), point p_w (3).
class ReprojectionFactor final : public ceres::SizedCostFunction<2, 7, 3> {
 public:
  /// observed_normalized: undistorted normalised coordinates (x, y) of the keypoint;
  /// sigma_px > 0: its standard deviation in pixels. Validates the camera (OptionError).
  ReprojectionFactor(const Eigen::Vector2d& observed_normalized, const ReprojectionCamera& camera,
                     double sigma_px);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  /// The whitened residual at a pose and point; nullopt when the point is not in front.
  std::optional<Eigen::Vector2d> residual(const SE3d& T_w_b, const Eigen::Vector3d& p_w) const;

 private:
  Eigen::Vector2d observed_;
  ReprojectionCamera camera_;
  double weight_;  ///< 1 / sigma_px.
};

/// Rectified stereo observation (3 residuals); the camera needs baseline_m > 0. Parameter blocks:
/// pose T_w_b (7), point p_w (3).
class StereoReprojectionFactor final : public ceres::SizedCostFunction<3, 7, 3> {
 public:
  /// observed: (x, y) normalised in the left camera and x_r normalised in the right camera.
  /// Throws OptionError when the camera is invalid or has no baseline, or sigma_px <= 0.
  StereoReprojectionFactor(const Eigen::Vector3d& observed, const ReprojectionCamera& camera,
                           double sigma_px);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  /// The whitened residual at a pose and point; nullopt when the point is not in front.
  std::optional<Eigen::Vector3d> residual(const SE3d& T_w_b, const Eigen::Vector3d& p_w) const;

 private:
  Eigen::Vector3d observed_;
  ReprojectionCamera camera_;
  double weight_;  ///< 1 / sigma_px.
};

}  // namespace superdyna::optim

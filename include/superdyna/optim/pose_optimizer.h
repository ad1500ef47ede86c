#pragma once
// Motion-only bundle adjustment: the body pose T_w_b of one frame from 2D-3D matches against fixed
// map points, with outlier classification, and optionally a Gaussian prior on the pose (e.g. the
// IMU-predicted pose).
//
// Procedure: `rounds` times, (1) optimise the pose over the matches currently classified as
// inliers (Huber loss in the first `robust_rounds` rounds, plain least squares after), then (2)
// re-classify EVERY match by the chi^2 test of its whitened residual at the new pose, so matches
// rejected earlier come back when the pose has moved towards them. Matches behind the camera are
// outliers.

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/optim/reprojection_factor.h"

namespace superdyna::optim {

/// One 2D-3D match.
struct PoseObservation {
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();  ///< Map point [m], held fixed.
  /// Undistorted normalised coordinates (x, y) of the keypoint in camera `camera`.
  Eigen::Vector2d normalized = Eigen::Vector2d::Zero();
  /// Rectified stereo: normalised x of the match in the right camera (the camera needs
  /// baseline_m > 0); nullopt for a monocular observation.
  std::optional<double> right_x;
  int octave = 0;  ///< Pyramid level: sigma = sigma0_px * scale_factor^octave.
  int camera = 0;  ///< Index into the cameras passed to PoseOptimizer::optimize().
};

/// Gaussian prior on the pose, in the convention of PosePriorFactor (imu_factors.h).
struct PosePrior {
  SE3d T_w_b;  ///< Mean, e.g. the IMU-predicted pose.
  /// Information (inverse covariance, symmetric positive definite) of the error
  /// [Log(R_prior^T R_w_b) (body frame) [rad]; p_w - p_prior (world frame) [m]].
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Identity();
};

struct PoseOptimizerOptions {
  int rounds = 4;                 ///< Optimise + classify rounds. Default 4 (ORB-SLAM).
  int iterations_per_round = 10;  ///< Levenberg-Marquardt iterations per round. Default 10.
  /// Rounds (from the first) that use the Huber loss; the rest fit the inliers by plain least
  /// squares. Default 3: the last round is not robustified (ORB-SLAM).
  int robust_rounds = 3;
  double sigma0_px = 1.0;              ///< Keypoint standard deviation at octave 0 [px]. Default 1.
  double scale_factor = 1.2;           ///< Pyramid scale between octaves. Default 1.2 (ORB).
  double chi2_mono = kChi2Mono95;      ///< Inlier threshold, 2 dof. Default 5.991 (95 %).
  double chi2_stereo = kChi2Stereo95;  ///< Inlier threshold, 3 dof. Default 7.815 (95 %).
  /// Fewer inliers than this stops the rounds early (the pose is kept from the last round) and
  /// the result is not a success. Default 10.
  int min_inliers = 10;

  /// Throws OptionError for non-positive counts, sigma or thresholds, scale_factor < 1, or
  /// robust_rounds outside [0, rounds].
  void validate() const;
  bool operator==(const PoseOptimizerOptions&) const = default;
};

struct PoseOptimizationResult {
  SE3d T_w_b;                 ///< The optimised pose.
  std::vector<bool> inliers;  ///< Per observation, from the classification after the last round.
  /// Per observation: squared whitened residual at T_w_b (infinity when behind the camera).
  std::vector<double> chi2;
  int num_inliers = 0;
  int rounds_run = 0;    ///< Optimisation rounds actually run.
  bool success = false;  ///< num_inliers >= min_inliers.
};

class PoseOptimizer {
 public:
  /// Validates the options (OptionError).
  explicit PoseOptimizer(PoseOptimizerOptions options = {});

  const PoseOptimizerOptions& options() const { return options_; }

  /// Optimises T_w_b from its initial value. Throws std::invalid_argument when an observation
  /// names a camera outside `cameras` or is stereo on a camera without baseline, and OptionError
  /// for an invalid camera or a prior information that is not symmetric positive definite.
  PoseOptimizationResult optimize(const SE3d& T_w_b_initial,
                                  const std::vector<ReprojectionCamera>& cameras,
                                  const std::vector<PoseObservation>& observations,
                                  const std::optional<PosePrior>& prior = std::nullopt) const;

 private:
  void validateInputs(const std::vector<ReprojectionCamera>& cameras,
                      const std::vector<PoseObservation>& observations) const;
  /// A new cost function for one observation (owned by the caller).
  ceres::CostFunction* newCostFunction(const PoseObservation& observation,
                                       const ReprojectionCamera& camera) const;
  /// Squared whitened residual at T_w_b; infinity when the point is behind the camera.
  double chi2(const PoseObservation& observation, const ReprojectionCamera& camera,
              const SE3d& T_w_b) const;
  double chi2Threshold(const PoseObservation& observation) const;
  /// Fills result.chi2, result.inliers and result.num_inliers at result.T_w_b.
  void classify(const std::vector<ReprojectionCamera>& cameras,
                const std::vector<PoseObservation>& observations,
                PoseOptimizationResult& result) const;
  /// One optimisation (PoseLeastSquares, iterations_per_round) from current.T_w_b over the
  /// observations current.inliers flags whose current.chi2 (classify() at that pose) is finite
  /// (in front of the camera); returns the new pose.
  SE3d optimizeOnce(const PoseOptimizationResult& current,
                    const std::vector<ReprojectionCamera>& cameras,
                    const std::vector<PoseObservation>& observations, bool robust,
                    const std::optional<PosePrior>& prior) const;

  PoseOptimizerOptions options_;
};

}  // namespace superdyna::optim

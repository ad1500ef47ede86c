#pragma once
// Inertial-only initialisation (the "inertial-only MAP estimation" of ORB-SLAM3, Campos et al.,
// IEEE TRO 2021, in its simplest useful form): with the keyframe poses from vision held fixed,
// find the gravity direction, the scale of the visual map (monocular), the keyframe velocities
// and one bias shared by the whole window, by non-linear least squares (Ceres) over the
// preintegrated IMU residuals between consecutive keyframes.
//
// Frames: v is the frame of the visual map (arbitrary orientation, for monocular also arbitrary
// scale), w a gravity-aligned world frame (z up). The poses are those of the body (IMU) frame:
// T_v_b = T_v_c * T_c_b. With a monocular map the camera-to-IMU translation should be small
// against the motion, or be applied by the caller at the estimated scale and the problem re-run.
//
// Residual between keyframes i and j (poses fixed, s the scale, g_v = kGravity * u_v with u_v the
// unit gravity direction in v):
//   r_R = Log(dR(bg)^T R_v_i^T R_v_j)
//   r_V = R_v_i^T (v_j - v_i - g_v dt) - dV(bg, ba)
//   r_P = R_v_i^T (s (p_j - p_i) - v_i dt - g_v dt^2 / 2) - dP(bg, ba)
// whitened by the preintegrated covariance, plus Gaussian priors on bg and ba. Velocities are
// metric and expressed in v. Between solver rounds the preintegrations are re-integrated at the
// estimated bias, so that the first-order bias correction stays accurate.

#include <Eigen/Core>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/imu/preintegration.h"

namespace superdyna::imu {

/// Options of initializeInertial().
struct InertialInitOptions {
  /// Estimate the scale of the visual poses (monocular); when false it is fixed at
  /// initial_scale (stereo / RGB-D: 1).
  bool estimate_scale = true;
  double initial_scale = 1.0;  ///< Metric length of one visual unit, > 0.
  /// Prior std of the gyroscope bias around zero [rad/s], > 0.
  double gyro_bias_prior_sigma = 1.0;
  /// Prior std of the accelerometer bias around zero [m/s^2], > 0. ORB-SLAM3 holds ba near zero
  /// in its first monocular initialisation (weakly observable under little rotation); loosen it
  /// when the motion is rich.
  double accel_bias_prior_sigma = 1.0;
  int max_iterations = 100;  ///< Ceres iterations per round, >= 1.
  int reintegration_rounds =
      2;  ///< Extra solver rounds after re-integrating at the estimate, >= 0.
  /// Let Ceres compare the analytic Jacobians with finite differences at every step (slow; the
  /// solve then throws std::runtime_error on a mismatch). For tests.
  bool check_gradients = false;

  /// Throws OptionError naming the first invalid field.
  void validate() const;
};

/// Keyframes with their fixed visual poses and the preintegrations between consecutive ones.
struct InertialInitInput {
  std::vector<SE3d> T_v_b;  ///< Body pose of each keyframe in the visual frame (N >= 3).
  /// preintegrations[k] spans keyframes k -> k + 1 (N - 1 entries); their linearisation biases
  /// are the initial bias guess (the mean of them is used).
  std::vector<Preintegration> preintegrations;
};

/// Result of initializeInertial().
struct InertialInitResult {
  Eigen::Vector3d gravity_dir_v = Eigen::Vector3d::UnitZ();  ///< Unit gravity direction in v.
  /// Rotation from v to a z-up world frame, R_w_v * gravity_dir_v = (0, 0, -1); the yaw about the
  /// world z axis is unobservable and chosen as the smallest rotation.
  Eigen::Matrix3d R_w_v = Eigen::Matrix3d::Identity();
  double scale = 1.0;                ///< Metric length of one visual unit.
  std::vector<Eigen::Vector3d> v_v;  ///< Keyframe velocities in v [m/s] (metric).
  Bias bias;                         ///< Bias shared by the window.
  double initial_cost = 0.0;         ///< Ceres cost (1/2 sum of squares) of the first guess.
  double final_cost = 0.0;           ///< Ceres cost after the last round.
  int iterations = 0;                ///< Solver iterations over all rounds.
  bool converged = false;            ///< Whether the last round reached a convergence test.
};

/// Estimates gravity direction, scale, velocities and bias from fixed visual poses and the IMU.
/// The first guess is: gravity opposite to sum_k R_v_k dV_k, velocities from position
/// differences, the mean linearisation bias. Throws OptionError for invalid options or input
/// (fewer than 3 keyframes, preintegration count not N - 1), std::runtime_error when Ceres
/// reports a failure.
InertialInitResult initializeInertial(const InertialInitInput& input,
                                      const InertialInitOptions& options = {});

/// The smallest rotation R_w_v with R_w_v * gravity_dir_v = (0, 0, -1) (gravity_dir_v unit).
Eigen::Matrix3d gravityAlignedRotation(const Eigen::Vector3d& gravity_dir_v);

}  // namespace superdyna::imu

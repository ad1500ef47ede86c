#pragma once
// Ceres cost functions for visual-inertial optimisation with preintegrated IMU measurements
// (Forster et al., TRO 2017; ORB-SLAM3), with analytic Jacobians.
//
// Parameter blocks of one IMU state (frames: w world z-up, b body = IMU):
//   pose       7 doubles T_w_b, the pose block of se3_manifold.h (quaternion x, y, z, w, then
//              p_w [m]; manifold SE3Manifold, a left update R <- Exp(2 dq) R).
//   velocity   3 doubles v_w [m/s].
//   bias_gyro  3 doubles bg [rad/s].
//   bias_acc   3 doubles ba [m/s^2].
// The Jacobians are with respect to the ambient parameters (4 quaternion coefficients, as Ceres
// expects); the residuals normalise the quaternion, so they are exact in all four directions and
// independent of the manifold's tangent convention.

#include <ceres/ceres.h>
#include <ceres/product_manifold.h>

#include <Eigen/Core>
#include <array>

#include "superdyna/core/geometry.h"
#include "superdyna/imu/preintegration.h"
#include "superdyna/optim/se3_manifold.h"

namespace superdyna::optim {

/// Pointers to the parameter blocks of one IMU state (owned by the caller, kept alive while the
/// problem is).
struct ImuStateBlocks {
  double* pose = nullptr;       ///< 7: T_w_b.
  double* velocity = nullptr;   ///< 3: v_w [m/s].
  double* bias_gyro = nullptr;  ///< 3: bg [rad/s].
  double* bias_acc = nullptr;   ///< 3: ba [m/s^2].
};

/// Storage for one IMU state in the layout above.
struct ImuStateParameters {
  std::array<double, kPoseBlockSize> pose = {0, 0, 0, 1, 0, 0, 0};
  std::array<double, 3> velocity = {0, 0, 0};
  std::array<double, 3> bias_gyro = {0, 0, 0};
  std::array<double, 3> bias_acc = {0, 0, 0};

  static ImuStateParameters from(const imu::NavState& state, const imu::Bias& bias);
  imu::NavState navState() const;
  imu::Bias bias() const;
  ImuStateBlocks blocks();
};

/// Preintegrated IMU residual between states i and j (9 rows):
///   r_R = Log(dR(bg_i)^T R_i^T R_j)
///   r_V = R_i^T (v_j - v_i - g dt) - dV(bg_i, ba_i)
///   r_P = R_i^T (p_j - p_i - v_i dt - g dt^2 / 2) - dP(bg_i, ba_i)
/// with the first-order bias corrections of imu::Preintegration, whitened by
/// covariance^(-1/2) of the preintegration (so a consistent residual has unit covariance).
/// Parameter blocks: pose_i (7), velocity_i (3), bias_gyro_i (3), bias_acc_i (3), pose_j (7),
/// velocity_j (3).
class ImuPreintegrationFactor final : public ceres::SizedCostFunction<9, 7, 3, 3, 3, 7, 3> {
 public:
  /// Copies the preintegration. Throws OptionError when it is empty or its covariance is not
  /// positive definite.
  explicit ImuPreintegrationFactor(const imu::Preintegration& preintegration);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  /// The residual before whitening, for diagnostics.
  Eigen::Matrix<double, 9, 1> unwhitenedResidual(const imu::NavState& state_i,
                                                 const imu::Bias& bias_i,
                                                 const imu::NavState& state_j) const;

  const imu::Preintegration& preintegration() const { return preintegration_; }
  /// covariance^(-1/2) of the preintegration.
  const imu::Matrix9d& sqrtInformation() const { return sqrt_information_; }

 private:
  imu::Preintegration preintegration_;
  imu::Matrix9d sqrt_information_;
};

/// Bias random walk between states i and j, dt_s apart (6 rows):
///   r = [(bg_j - bg_i) / (gyro_random_walk sqrt(dt)); (ba_j - ba_i) / (accel_random_walk
///   sqrt(dt))]
/// Parameter blocks: bias_gyro_i (3), bias_acc_i (3), bias_gyro_j (3), bias_acc_j (3).
class BiasRandomWalkFactor final : public ceres::SizedCostFunction<6, 3, 3, 3, 3> {
 public:
  /// Throws OptionError when the noise is invalid or dt_s is not positive.
  BiasRandomWalkFactor(const imu::ImuNoise& noise, double dt_s);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  double gyroWeight() const { return gyro_weight_; }    ///< 1 / (sigma_rw_g sqrt(dt)).
  double accelWeight() const { return accel_weight_; }  ///< 1 / (sigma_rw_a sqrt(dt)).

 private:
  double gyro_weight_;
  double accel_weight_;
};

/// Gaussian prior on a 3-vector block (a bias or a velocity): r = S (x - mean), S =
/// covariance^(-1/2). Parameter block: the vector (3).
class Vector3PriorFactor final : public ceres::SizedCostFunction<3, 3> {
 public:
  /// Throws OptionError when the covariance is not symmetric positive definite.
  Vector3PriorFactor(const Eigen::Vector3d& mean, const Eigen::Matrix3d& covariance);
  /// Isotropic prior with standard deviation sigma > 0 (units of the vector).
  Vector3PriorFactor(const Eigen::Vector3d& mean, double sigma);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Eigen::Vector3d mean_;
  Eigen::Matrix3d sqrt_information_;
};

/// Gaussian prior on a pose block: r = S [Log(R_prior^T R); p - p_prior] (rotation error in the
/// body frame [rad], position error in the world frame [m]), S = covariance^(-1/2) (6x6, same
/// order). Parameter block: pose (7).
class PosePriorFactor final : public ceres::SizedCostFunction<6, 7> {
 public:
  /// Throws OptionError when the covariance is not symmetric positive definite.
  PosePriorFactor(const SE3d& T_w_b_prior, const imu::Matrix6d& covariance);
  /// Isotropic prior: rotation std [rad] and position std [m], both > 0.
  PosePriorFactor(const SE3d& T_w_b_prior, double sigma_rotation_rad, double sigma_position_m);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Eigen::Matrix3d R_w_prior_;
  Eigen::Vector3d p_w_prior_;
  imu::Matrix6d sqrt_information_;
};

/// Adds the four blocks of a state to the problem, the pose with a SE3Manifold (unless the pose
/// block already has a manifold). The problem must own its manifolds (the default
/// ceres::Problem::Options::manifold_ownership = TAKE_OWNERSHIP).
void addImuStateBlocks(ceres::Problem& problem, const ImuStateBlocks& state);

/// Adds an ImuPreintegrationFactor between states i and j (their blocks are added first with
/// addImuStateBlocks). `loss` may be null; the problem takes ownership of it.
ceres::ResidualBlockId addImuPreintegrationFactor(ceres::Problem& problem,
                                                  const imu::Preintegration& preintegration,
                                                  const ImuStateBlocks& state_i,
                                                  const ImuStateBlocks& state_j,
                                                  ceres::LossFunction* loss = nullptr);

/// Adds a BiasRandomWalkFactor over dt_s seconds between the biases of states i and j.
ceres::ResidualBlockId addBiasRandomWalkFactor(ceres::Problem& problem, const imu::ImuNoise& noise,
                                               double dt_s, const ImuStateBlocks& state_i,
                                               const ImuStateBlocks& state_j);

/// Residual blocks added for one pair of consecutive IMU states.
struct ImuEdge {
  ceres::ResidualBlockId preintegration = nullptr;
  ceres::ResidualBlockId bias_random_walk = nullptr;
};

/// The usual pair of factors between consecutive keyframes: preintegration and bias random walk
/// (over the preintegration's time span, with its noise model). Adds the state blocks.
ImuEdge addImuEdge(ceres::Problem& problem, const imu::Preintegration& preintegration,
                   const ImuStateBlocks& state_i, const ImuStateBlocks& state_j,
                   ceres::LossFunction* loss = nullptr);

/// Isotropic priors on both biases of a state (the initialisation anchor): sigma_gyro [rad/s],
/// sigma_acc [m/s^2] around `mean`. Returns the two residual blocks (gyro, acc).
std::array<ceres::ResidualBlockId, 2> addBiasPrior(ceres::Problem& problem,
                                                   const ImuStateBlocks& state,
                                                   const imu::Bias& mean, double sigma_gyro,
                                                   double sigma_acc);

}  // namespace superdyna::optim

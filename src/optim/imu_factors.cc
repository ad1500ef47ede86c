#include "superdyna/optim/imu_factors.h"

#include <Eigen/Geometry>
#include <cmath>

#include "superdyna/core/error.h"

namespace superdyna::optim {

namespace {

using Vector9d = Eigen::Matrix<double, 9, 1>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

/// Writes a matrix into Ceres' row-major storage.
template <int Rows, int Cols>
void store(const Eigen::Matrix<double, Rows, Cols>& M, double* out) {
  constexpr int kOrder = Cols == 1 ? Eigen::ColMajor : Eigen::RowMajor;
  Eigen::Map<Eigen::Matrix<double, Rows, Cols, kOrder>> map(out);
  map = M;
}

/// A pose block read as rotation and position.
struct PoseView {
  explicit PoseView(const double* pose)
      : q_raw(pose),
        q(Eigen::Quaterniond(pose[3], pose[0], pose[1], pose[2]).normalized()),
        R(q.toRotationMatrix()),
        p(pose[4], pose[5], pose[6]) {}

  /// d(dtheta) / d(quaternion coefficients x, y, z, w) at this block, dtheta the rotation vector
  /// of a left (world-frame) perturbation Exp(dtheta) R of the normalised quaternion: combined
  /// with the Jacobian for dtheta it gives the exact ambient Jacobian of a residual that
  /// normalises the quaternion (zero along the quaternion itself).
  Eigen::Matrix<double, 3, 4> leftTangentFromAmbient() const {
    const double norm = Eigen::Map<const Eigen::Vector4d>(q_raw).norm();
    Eigen::Matrix<double, 3, 4> L;
    L.leftCols<3>() = q.w() * Eigen::Matrix3d::Identity() + hat(q.vec());
    L.col(3) = -q.vec();
    return (2.0 / norm) * L;
  }

  /// The ambient Jacobian of a pose block from the Jacobians for a right rotation perturbation
  /// R Exp(phi) and for the world position.
  template <int Rows>
  Eigen::Matrix<double, Rows, 7> ambient(const Eigen::Matrix<double, Rows, 3>& J_phi_right,
                                         const Eigen::Matrix<double, Rows, 3>& J_p) const {
    Eigen::Matrix<double, Rows, 7> J;
    // Exp(delta) R = R Exp(R^T delta): the left Jacobian is J_right R^T.
    J.template leftCols<4>() = J_phi_right * R.transpose() * leftTangentFromAmbient();
    J.template rightCols<3>() = J_p;
    return J;
  }

  const double* q_raw;
  Eigen::Quaterniond q;
  Eigen::Matrix3d R;
  Eigen::Vector3d p;
};

void requirePositive(double value, const char* name) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw OptionError(name, "must be a positive finite number");
  }
}

}  // namespace

ImuStateParameters ImuStateParameters::from(const imu::NavState& state, const imu::Bias& bias) {
  ImuStateParameters out;
  out.pose = toPoseBlock(SE3d(state.R_w_b, state.p_w));
  Eigen::Map<Eigen::Vector3d>(out.velocity.data()) = state.v_w;
  Eigen::Map<Eigen::Vector3d>(out.bias_gyro.data()) = bias.bg;
  Eigen::Map<Eigen::Vector3d>(out.bias_acc.data()) = bias.ba;
  return out;
}

imu::NavState ImuStateParameters::navState() const {
  const PoseView view(pose.data());
  return {view.R, view.p, Eigen::Map<const Eigen::Vector3d>(velocity.data())};
}

imu::Bias ImuStateParameters::bias() const {
  return {Eigen::Map<const Eigen::Vector3d>(bias_gyro.data()),
          Eigen::Map<const Eigen::Vector3d>(bias_acc.data())};
}

ImuStateBlocks ImuStateParameters::blocks() {
  return {pose.data(), velocity.data(), bias_gyro.data(), bias_acc.data()};
}

// ---------------------------------------------------------------------------------------------
// ImuPreintegrationFactor

ImuPreintegrationFactor::ImuPreintegrationFactor(const imu::Preintegration& preintegration)
    : preintegration_(preintegration) {
  if (!(preintegration.deltaTime() > 0.0)) {
    throw OptionError("preintegration", "must span a positive time");
  }
  sqrt_information_ = imu::inverseSquareRoot<9>(preintegration.covariance());
}

Eigen::Matrix<double, 9, 1> ImuPreintegrationFactor::unwhitenedResidual(
    const imu::NavState& state_i, const imu::Bias& bias_i, const imu::NavState& state_j) const {
  const imu::Preintegration& pre = preintegration_;
  const double dt = pre.deltaTime();
  const Eigen::Vector3d g_w = imu::gravityVector();
  const Eigen::Matrix3d R_i_w = state_i.R_w_b.transpose();
  Vector9d r;
  r.segment<3>(0) = logSO3(pre.correctedDeltaRotation(bias_i).transpose() * R_i_w * state_j.R_w_b);
  r.segment<3>(3) =
      R_i_w * (state_j.v_w - state_i.v_w - g_w * dt) - pre.correctedDeltaVelocity(bias_i);
  r.segment<3>(6) = R_i_w * (state_j.p_w - state_i.p_w - state_i.v_w * dt - 0.5 * g_w * dt * dt) -
                    pre.correctedDeltaPosition(bias_i);
  return r;
}

bool ImuPreintegrationFactor::Evaluate(double const* const* parameters, double* residuals,
                                       double** jacobians) const {
  const PoseView pose_i(parameters[0]);
  const Eigen::Map<const Eigen::Vector3d> v_i(parameters[1]);
  imu::Bias bias_i;
  bias_i.bg = Eigen::Map<const Eigen::Vector3d>(parameters[2]);
  bias_i.ba = Eigen::Map<const Eigen::Vector3d>(parameters[3]);
  const PoseView pose_j(parameters[4]);
  const Eigen::Map<const Eigen::Vector3d> v_j(parameters[5]);

  const imu::Preintegration& pre = preintegration_;
  const double dt = pre.deltaTime();
  const Eigen::Vector3d g_w = imu::gravityVector();
  const Eigen::Matrix3d R_i_w = pose_i.R.transpose();
  const Eigen::Vector3d J_R_dbg = pre.J_R_bg() * (bias_i.bg - pre.linearizationBias().bg);
  const Eigen::Matrix3d dR_corrected = pre.deltaRotation() * expSO3(J_R_dbg);
  const Eigen::Matrix3d E = dR_corrected.transpose() * R_i_w * pose_j.R;
  const Eigen::Vector3d dv_w = v_j - v_i - g_w * dt;
  const Eigen::Vector3d dp_w = pose_j.p - pose_i.p - v_i * dt - 0.5 * g_w * dt * dt;

  Vector9d r;
  r.segment<3>(0) = logSO3(E);
  r.segment<3>(3) = R_i_w * dv_w - pre.correctedDeltaVelocity(bias_i);
  r.segment<3>(6) = R_i_w * dp_w - pre.correctedDeltaPosition(bias_i);
  store<9, 1>(sqrt_information_ * r, residuals);
  if (jacobians == nullptr) return true;

  using Matrix93 = Eigen::Matrix<double, 9, 3>;
  const Eigen::Matrix3d Jr_inv = rightJacobianInverseSO3(r.segment<3>(0));
  if (jacobians[0] != nullptr) {
    Matrix93 J_phi = Matrix93::Zero();
    J_phi.block<3, 3>(0, 0) = -Jr_inv * pose_j.R.transpose() * pose_i.R;
    J_phi.block<3, 3>(3, 0) = hat(R_i_w * dv_w);
    J_phi.block<3, 3>(6, 0) = hat(R_i_w * dp_w);
    Matrix93 J_p = Matrix93::Zero();
    J_p.block<3, 3>(6, 0) = -R_i_w;
    store<9, 7>(sqrt_information_ * pose_i.ambient<9>(J_phi, J_p), jacobians[0]);
  }
  if (jacobians[1] != nullptr) {
    Matrix93 J = Matrix93::Zero();
    J.block<3, 3>(3, 0) = -R_i_w;
    J.block<3, 3>(6, 0) = -R_i_w * dt;
    store<9, 3>(sqrt_information_ * J, jacobians[1]);
  }
  if (jacobians[2] != nullptr) {
    Matrix93 J;
    J.block<3, 3>(0, 0) = -Jr_inv * E.transpose() * rightJacobianSO3(J_R_dbg) * pre.J_R_bg();
    J.block<3, 3>(3, 0) = -pre.J_V_bg();
    J.block<3, 3>(6, 0) = -pre.J_P_bg();
    store<9, 3>(sqrt_information_ * J, jacobians[2]);
  }
  if (jacobians[3] != nullptr) {
    Matrix93 J = Matrix93::Zero();
    J.block<3, 3>(3, 0) = -pre.J_V_ba();
    J.block<3, 3>(6, 0) = -pre.J_P_ba();
    store<9, 3>(sqrt_information_ * J, jacobians[3]);
  }
  if (jacobians[4] != nullptr) {
    Matrix93 J_phi = Matrix93::Zero();
    J_phi.block<3, 3>(0, 0) = Jr_inv;
    Matrix93 J_p = Matrix93::Zero();
    J_p.block<3, 3>(6, 0) = R_i_w;
    store<9, 7>(sqrt_information_ * pose_j.ambient<9>(J_phi, J_p), jacobians[4]);
  }
  if (jacobians[5] != nullptr) {
    Matrix93 J = Matrix93::Zero();
    J.block<3, 3>(3, 0) = R_i_w;
    store<9, 3>(sqrt_information_ * J, jacobians[5]);
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// BiasRandomWalkFactor

BiasRandomWalkFactor::BiasRandomWalkFactor(const imu::ImuNoise& noise, double dt_s) {
  noise.validate();
  requirePositive(dt_s, "dt_s");
  gyro_weight_ = 1.0 / (noise.gyro_random_walk * std::sqrt(dt_s));
  accel_weight_ = 1.0 / (noise.accel_random_walk * std::sqrt(dt_s));
}

bool BiasRandomWalkFactor::Evaluate(double const* const* parameters, double* residuals,
                                    double** jacobians) const {
  const Eigen::Map<const Eigen::Vector3d> bg_i(parameters[0]);
  const Eigen::Map<const Eigen::Vector3d> ba_i(parameters[1]);
  const Eigen::Map<const Eigen::Vector3d> bg_j(parameters[2]);
  const Eigen::Map<const Eigen::Vector3d> ba_j(parameters[3]);
  Vector6d r;
  r.head<3>() = gyro_weight_ * (bg_j - bg_i);
  r.tail<3>() = accel_weight_ * (ba_j - ba_i);
  store<6, 1>(r, residuals);
  if (jacobians == nullptr) return true;
  const double weights[4] = {-gyro_weight_, -accel_weight_, gyro_weight_, accel_weight_};
  for (int k = 0; k < 4; ++k) {
    if (jacobians[k] == nullptr) continue;
    Eigen::Matrix<double, 6, 3> J = Eigen::Matrix<double, 6, 3>::Zero();
    J.block<3, 3>(k % 2 == 0 ? 0 : 3, 0) = weights[k] * Eigen::Matrix3d::Identity();
    store<6, 3>(J, jacobians[k]);
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Priors

Vector3PriorFactor::Vector3PriorFactor(const Eigen::Vector3d& mean,
                                       const Eigen::Matrix3d& covariance)
    : mean_(mean), sqrt_information_(imu::inverseSquareRoot<3>(covariance)) {}

Vector3PriorFactor::Vector3PriorFactor(const Eigen::Vector3d& mean, double sigma)
    : Vector3PriorFactor(mean, [&]() -> Eigen::Matrix3d {
        requirePositive(sigma, "sigma");
        return Eigen::Matrix3d::Identity() * sigma * sigma;
      }()) {}

bool Vector3PriorFactor::Evaluate(double const* const* parameters, double* residuals,
                                  double** jacobians) const {
  const Eigen::Map<const Eigen::Vector3d> x(parameters[0]);
  store<3, 1>(sqrt_information_ * (x - mean_), residuals);
  if (jacobians != nullptr && jacobians[0] != nullptr) store<3, 3>(sqrt_information_, jacobians[0]);
  return true;
}

PosePriorFactor::PosePriorFactor(const SE3d& T_w_b_prior, const imu::Matrix6d& covariance)
    : R_w_prior_(T_w_b_prior.rotation()),
      p_w_prior_(T_w_b_prior.t),
      sqrt_information_(imu::inverseSquareRoot<6>(covariance)) {}

PosePriorFactor::PosePriorFactor(const SE3d& T_w_b_prior, double sigma_rotation_rad,
                                 double sigma_position_m)
    : PosePriorFactor(T_w_b_prior, [&]() -> imu::Matrix6d {
        requirePositive(sigma_rotation_rad, "sigma_rotation_rad");
        requirePositive(sigma_position_m, "sigma_position_m");
        Vector6d variances;
        variances.head<3>().setConstant(sigma_rotation_rad * sigma_rotation_rad);
        variances.tail<3>().setConstant(sigma_position_m * sigma_position_m);
        return variances.asDiagonal();
      }()) {}

bool PosePriorFactor::Evaluate(double const* const* parameters, double* residuals,
                               double** jacobians) const {
  const PoseView pose(parameters[0]);
  Vector6d r;
  r.head<3>() = logSO3(R_w_prior_.transpose() * pose.R);
  r.tail<3>() = pose.p - p_w_prior_;
  store<6, 1>(sqrt_information_ * r, residuals);
  if (jacobians != nullptr && jacobians[0] != nullptr) {
    Eigen::Matrix<double, 6, 3> J_phi = Eigen::Matrix<double, 6, 3>::Zero();
    J_phi.topRows<3>() = rightJacobianInverseSO3(r.head<3>());
    Eigen::Matrix<double, 6, 3> J_p = Eigen::Matrix<double, 6, 3>::Zero();
    J_p.bottomRows<3>().setIdentity();
    store<6, 7>(sqrt_information_ * pose.ambient<6>(J_phi, J_p), jacobians[0]);
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Problem helpers

void addImuStateBlocks(ceres::Problem& problem, const ImuStateBlocks& state) {
  problem.AddParameterBlock(state.pose, kPoseBlockSize);
  if (!problem.HasManifold(state.pose)) problem.SetManifold(state.pose, new SE3Manifold());
  problem.AddParameterBlock(state.velocity, 3);
  problem.AddParameterBlock(state.bias_gyro, 3);
  problem.AddParameterBlock(state.bias_acc, 3);
}

ceres::ResidualBlockId addImuPreintegrationFactor(ceres::Problem& problem,
                                                  const imu::Preintegration& preintegration,
                                                  const ImuStateBlocks& state_i,
                                                  const ImuStateBlocks& state_j,
                                                  ceres::LossFunction* loss) {
  addImuStateBlocks(problem, state_i);
  addImuStateBlocks(problem, state_j);
  return problem.AddResidualBlock(new ImuPreintegrationFactor(preintegration), loss, state_i.pose,
                                  state_i.velocity, state_i.bias_gyro, state_i.bias_acc,
                                  state_j.pose, state_j.velocity);
}

ceres::ResidualBlockId addBiasRandomWalkFactor(ceres::Problem& problem, const imu::ImuNoise& noise,
                                               double dt_s, const ImuStateBlocks& state_i,
                                               const ImuStateBlocks& state_j) {
  addImuStateBlocks(problem, state_i);
  addImuStateBlocks(problem, state_j);
  return problem.AddResidualBlock(new BiasRandomWalkFactor(noise, dt_s), nullptr, state_i.bias_gyro,
                                  state_i.bias_acc, state_j.bias_gyro, state_j.bias_acc);
}

ImuEdge addImuEdge(ceres::Problem& problem, const imu::Preintegration& preintegration,
                   const ImuStateBlocks& state_i, const ImuStateBlocks& state_j,
                   ceres::LossFunction* loss) {
  ImuEdge edge;
  edge.preintegration = addImuPreintegrationFactor(problem, preintegration, state_i, state_j, loss);
  edge.bias_random_walk = addBiasRandomWalkFactor(problem, preintegration.noise(),
                                                  preintegration.deltaTime(), state_i, state_j);
  return edge;
}

std::array<ceres::ResidualBlockId, 2> addBiasPrior(ceres::Problem& problem,
                                                   const ImuStateBlocks& state,
                                                   const imu::Bias& mean, double sigma_gyro,
                                                   double sigma_acc) {
  addImuStateBlocks(problem, state);
  return {problem.AddResidualBlock(new Vector3PriorFactor(mean.bg, sigma_gyro), nullptr,
                                   state.bias_gyro),
          problem.AddResidualBlock(new Vector3PriorFactor(mean.ba, sigma_acc), nullptr,
                                   state.bias_acc)};
}

}  // namespace superdyna::optim

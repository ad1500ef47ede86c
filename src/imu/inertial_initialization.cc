#include "superdyna/imu/inertial_initialization.h"

#include <ceres/ceres.h>
#include <ceres/sphere_manifold.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <Eigen/Geometry>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "superdyna/core/error.h"

namespace superdyna::imu {

namespace {

using Vector9d = Eigen::Matrix<double, 9, 1>;

/// Writes a matrix into Ceres' row-major storage.
template <int Rows, int Cols>
void store(const Eigen::Matrix<double, Rows, Cols>& M, double* out) {
  constexpr int kOrder = Cols == 1 ? Eigen::ColMajor : Eigen::RowMajor;
  Eigen::Map<Eigen::Matrix<double, Rows, Cols, kOrder>> map(out);
  map = M;
}

/// Preintegrated IMU residual between two keyframes with fixed visual poses.
/// Parameter blocks: gravity direction u_v (3, unit), log scale (1), v_i (3), v_j (3), bg (3),
/// ba (3).
class GravityScaleResidual final : public ceres::SizedCostFunction<9, 3, 1, 3, 3, 3, 3> {
 public:
  GravityScaleResidual(const SE3d& T_v_i, const SE3d& T_v_j, const Preintegration& preintegration)
      : R_v_i_(T_v_i.rotation()),
        R_v_j_(T_v_j.rotation()),
        dp_v_(T_v_j.t - T_v_i.t),
        preintegration_(preintegration),
        sqrt_information_(inverseSquareRoot<9>(preintegration.covariance())) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Map<const Eigen::Vector3d> u_v(parameters[0]);
    const double scale = std::exp(parameters[1][0]);
    const Eigen::Map<const Eigen::Vector3d> v_i(parameters[2]);
    const Eigen::Map<const Eigen::Vector3d> v_j(parameters[3]);
    Bias bias;
    bias.bg = Eigen::Map<const Eigen::Vector3d>(parameters[4]);
    bias.ba = Eigen::Map<const Eigen::Vector3d>(parameters[5]);

    const Preintegration& pre = preintegration_;
    const double dt = pre.deltaTime();
    const Eigen::Vector3d g_v = kGravity * u_v;
    const Eigen::Matrix3d R_i_v = R_v_i_.transpose();
    const Eigen::Vector3d dbg = bias.bg - pre.linearizationBias().bg;
    const Eigen::Vector3d J_R_dbg = pre.J_R_bg() * dbg;
    const Eigen::Matrix3d E = (pre.deltaRotation() * expSO3(J_R_dbg)).transpose() * R_i_v * R_v_j_;

    Vector9d r;
    r.segment<3>(0) = logSO3(E);
    r.segment<3>(3) = R_i_v * (v_j - v_i - g_v * dt) - pre.correctedDeltaVelocity(bias);
    r.segment<3>(6) =
        R_i_v * (scale * dp_v_ - v_i * dt - 0.5 * g_v * dt * dt) - pre.correctedDeltaPosition(bias);
    store<9, 1>(sqrt_information_ * r, residuals);
    if (jacobians == nullptr) return true;

    const Eigen::Matrix3d Jr_inv = rightJacobianInverseSO3(r.segment<3>(0));
    if (jacobians[0] != nullptr) {
      Eigen::Matrix<double, 9, 3> J = Eigen::Matrix<double, 9, 3>::Zero();
      J.block<3, 3>(3, 0) = -kGravity * dt * R_i_v;
      J.block<3, 3>(6, 0) = -0.5 * kGravity * dt * dt * R_i_v;
      store<9, 3>(sqrt_information_ * J, jacobians[0]);
    }
    if (jacobians[1] != nullptr) {
      Vector9d J = Vector9d::Zero();
      J.segment<3>(6) = scale * (R_i_v * dp_v_);
      store<9, 1>(sqrt_information_ * J, jacobians[1]);
    }
    if (jacobians[2] != nullptr) {
      Eigen::Matrix<double, 9, 3> J = Eigen::Matrix<double, 9, 3>::Zero();
      J.block<3, 3>(3, 0) = -R_i_v;
      J.block<3, 3>(6, 0) = -dt * R_i_v;
      store<9, 3>(sqrt_information_ * J, jacobians[2]);
    }
    if (jacobians[3] != nullptr) {
      Eigen::Matrix<double, 9, 3> J = Eigen::Matrix<double, 9, 3>::Zero();
      J.block<3, 3>(3, 0) = R_i_v;
      store<9, 3>(sqrt_information_ * J, jacobians[3]);
    }
    if (jacobians[4] != nullptr) {
      Eigen::Matrix<double, 9, 3> J;
      J.block<3, 3>(0, 0) = -Jr_inv * E.transpose() * rightJacobianSO3(J_R_dbg) * pre.J_R_bg();
      J.block<3, 3>(3, 0) = -pre.J_V_bg();
      J.block<3, 3>(6, 0) = -pre.J_P_bg();
      store<9, 3>(sqrt_information_ * J, jacobians[4]);
    }
    if (jacobians[5] != nullptr) {
      Eigen::Matrix<double, 9, 3> J = Eigen::Matrix<double, 9, 3>::Zero();
      J.block<3, 3>(3, 0) = -pre.J_V_ba();
      J.block<3, 3>(6, 0) = -pre.J_P_ba();
      store<9, 3>(sqrt_information_ * J, jacobians[5]);
    }
    return true;
  }

 private:
  Eigen::Matrix3d R_v_i_;
  Eigen::Matrix3d R_v_j_;
  Eigen::Vector3d dp_v_;  ///< p_j - p_i in visual units.
  const Preintegration& preintegration_;
  Eigen::Matrix<double, 9, 9> sqrt_information_;
};

/// Isotropic Gaussian prior x ~ N(0, sigma^2 I) on a 3-vector.
class ZeroPrior final : public ceres::SizedCostFunction<3, 3> {
 public:
  explicit ZeroPrior(double sigma) : inv_sigma_(1.0 / sigma) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Map<const Eigen::Vector3d> x(parameters[0]);
    store<3, 1>(inv_sigma_ * x, residuals);
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      store<3, 3>(inv_sigma_ * Eigen::Matrix3d::Identity(), jacobians[0]);
    }
    return true;
  }

 private:
  double inv_sigma_;
};

void requirePositive(double value, const char* name) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw OptionError(name, "must be a positive finite number");
  }
}

void validateInput(const InertialInitInput& input) {
  const std::size_t n = input.T_v_b.size();
  if (n < 3) throw OptionError("T_v_b", fmt::format("needs at least 3 keyframes, got {}", n));
  if (input.preintegrations.size() + 1 != n) {
    throw OptionError("preintegrations", fmt::format("needs {} entries (one per consecutive "
                                                     "keyframe pair), got {}",
                                                     n - 1, input.preintegrations.size()));
  }
  for (const Preintegration& pre : input.preintegrations) {
    if (!(pre.deltaTime() > 0.0)) throw OptionError("preintegrations", "must not be empty");
  }
}

/// The unknowns, stored as Ceres parameter blocks.
struct InitState {
  Eigen::Vector3d u_v;  ///< Unit gravity direction in v.
  double log_scale = 0.0;
  std::vector<Eigen::Vector3d> v_v;
  Eigen::Vector3d bg;
  Eigen::Vector3d ba;
};

InitState firstGuess(const InertialInitInput& input, const InertialInitOptions& options) {
  const std::size_t n = input.T_v_b.size();
  InitState state;
  // v_j - v_i = g dt + R_i dV over the window: gravity opposes the summed velocity deltas.
  Eigen::Vector3d sum_dV = Eigen::Vector3d::Zero();
  state.bg.setZero();
  state.ba.setZero();
  for (std::size_t k = 0; k + 1 < n; ++k) {
    const Preintegration& pre = input.preintegrations[k];
    sum_dV += input.T_v_b[k].q * pre.deltaVelocity();
    state.bg += pre.linearizationBias().bg / static_cast<double>(n - 1);
    state.ba += pre.linearizationBias().ba / static_cast<double>(n - 1);
  }
  state.u_v =
      sum_dV.norm() > 0.0 ? Eigen::Vector3d(-sum_dV.normalized()) : Eigen::Vector3d(0.0, 0.0, -1.0);
  state.log_scale = std::log(options.initial_scale);
  // Velocities from the scaled position differences to the neighbours.
  state.v_v.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t a = k == 0 ? 0 : k - 1;
    const std::size_t b = k + 1 == n ? k : k + 1;
    double dt = 0.0;
    for (std::size_t m = a; m < b; ++m)
      dt += input.preintegrations[m].deltaTime();
    state.v_v[k] = options.initial_scale * (input.T_v_b[b].t - input.T_v_b[a].t) / dt;
  }
  return state;
}

/// One Ceres solve of the whole window; updates `state` in place.
ceres::Solver::Summary solveRound(const InertialInitInput& input,
                                  const std::vector<Preintegration>& preintegrations,
                                  const InertialInitOptions& options, InitState& state) {
  ceres::Problem problem;
  problem.AddParameterBlock(state.u_v.data(), 3, new ceres::SphereManifold<3>());
  problem.AddParameterBlock(&state.log_scale, 1);
  if (!options.estimate_scale) problem.SetParameterBlockConstant(&state.log_scale);
  for (std::size_t k = 0; k + 1 < input.T_v_b.size(); ++k) {
    problem.AddResidualBlock(
        new GravityScaleResidual(input.T_v_b[k], input.T_v_b[k + 1], preintegrations[k]), nullptr,
        state.u_v.data(), &state.log_scale, state.v_v[k].data(), state.v_v[k + 1].data(),
        state.bg.data(), state.ba.data());
  }
  problem.AddResidualBlock(new ZeroPrior(options.gyro_bias_prior_sigma), nullptr, state.bg.data());
  problem.AddResidualBlock(new ZeroPrior(options.accel_bias_prior_sigma), nullptr, state.ba.data());

  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_QR;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.function_tolerance = 1e-10;
  solver_options.gradient_tolerance = 1e-12;
  solver_options.parameter_tolerance = 1e-10;
  solver_options.logging_type = ceres::SILENT;
  solver_options.num_threads = 1;
  solver_options.check_gradients = options.check_gradients;
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
  return summary;
}

}  // namespace

void InertialInitOptions::validate() const {
  requirePositive(initial_scale, "initial_scale");
  requirePositive(gyro_bias_prior_sigma, "gyro_bias_prior_sigma");
  requirePositive(accel_bias_prior_sigma, "accel_bias_prior_sigma");
  if (max_iterations < 1) throw OptionError("max_iterations", "must be at least 1");
  if (reintegration_rounds < 0) throw OptionError("reintegration_rounds", "must not be negative");
}

Eigen::Matrix3d gravityAlignedRotation(const Eigen::Vector3d& gravity_dir_v) {
  return Eigen::Quaterniond::FromTwoVectors(gravity_dir_v, Eigen::Vector3d(0.0, 0.0, -1.0))
      .toRotationMatrix();
}

InertialInitResult initializeInertial(const InertialInitInput& input,
                                      const InertialInitOptions& options) {
  options.validate();
  validateInput(input);
  InitState state = firstGuess(input, options);
  std::vector<Preintegration> preintegrations = input.preintegrations;

  InertialInitResult result;
  for (int round = 0; round <= options.reintegration_rounds; ++round) {
    if (round > 0) {
      for (Preintegration& pre : preintegrations)
        pre.reintegrate({state.bg, state.ba});
    }
    const ceres::Solver::Summary summary = solveRound(input, preintegrations, options, state);
    if (round == 0) result.initial_cost = summary.initial_cost;
    result.final_cost = summary.final_cost;
    result.iterations += summary.num_successful_steps + summary.num_unsuccessful_steps;
    result.converged = summary.termination_type == ceres::CONVERGENCE;
    if (!summary.IsSolutionUsable()) {
      spdlog::warn("inertial initialisation over {} keyframes failed (round {}): {}",
                   input.T_v_b.size(), round, summary.message);
      throw std::runtime_error("inertial initialisation: Ceres failed: " + summary.message);
    }
  }
  result.gravity_dir_v = state.u_v.normalized();
  result.R_w_v = gravityAlignedRotation(result.gravity_dir_v);
  result.scale = std::exp(state.log_scale);
  result.v_v = state.v_v;
  result.bias = {state.bg, state.ba};
  return result;
}

}  // namespace superdyna::imu

#include "superdyna/optim/pose_least_squares.h"

#include <ceres/loss_function.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <array>
#include <stdexcept>
#include <string>

#include "superdyna/optim/se3_manifold.h"

namespace superdyna::optim {

namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// rho(s) and rho'(s) (the residual's weight in the normal equations) of a squared residual
/// norm s under Ceres' HuberLoss(delta); s and 1 without a threshold.
std::array<double, 3> robustified(double s, double delta) {
  std::array<double, 3> rho = {s, 1.0, 0.0};
  if (delta > 0.0) ceres::HuberLoss(delta).Evaluate(s, rho.data());
  return rho;
}

/// Evaluates one term at a pose block: its residuals, and with `jacobian` their derivative by the
/// 7 block coordinates. False when the cost function cannot be evaluated there.
bool evaluateTerm(const PoseTerm& term, const PoseBlock& block, double* residuals,
                  double* jacobian) {
  const double* parameters[2] = {block.data(), term.point};
  double* jacobians[2] = {jacobian, nullptr};
  return term.factor->Evaluate(parameters, residuals, jacobian ? jacobians : nullptr);
}

/// The damped step: (H + lambda diag(H)) step = -g, the diagonal clamped as Ceres does.
Vector6d dampedStep(const Matrix6d& H, const Vector6d& g, double lambda) {
  Matrix6d damped = H;
  damped.diagonal() += lambda * H.diagonal().cwiseMax(1e-6).cwiseMin(1e32);
  return damped.ldlt().solve(-g);
}

}  // namespace

struct PoseLeastSquares::NormalEquations {
  Matrix6d H = Matrix6d::Zero();  ///< J^T W J in the tangent [dq, dp].
  Vector6d g = Vector6d::Zero();  ///< J^T W r.
  double cost = 0.0;
};

PoseLeastSquares::PoseLeastSquares(std::vector<PoseTerm> terms, PoseLeastSquaresOptions options)
    : terms_(std::move(terms)), options_(options) {
  for (const PoseTerm& term : terms_) {
    if (term.factor == nullptr || term.factor->num_residuals() > kMaxPoseTermResiduals) {
      throw std::invalid_argument("PoseLeastSquares: a term needs a cost function of at most " +
                                  std::to_string(kMaxPoseTermResiduals) + " residuals");
    }
  }
}

std::optional<double> PoseLeastSquares::cost(const SE3d& T_w_b) const {
  const PoseBlock block = toPoseBlock(T_w_b);
  std::array<double, kMaxPoseTermResiduals> r{};
  double total = 0.0;
  for (const PoseTerm& term : terms_) {
    if (!evaluateTerm(term, block, r.data(), nullptr)) return std::nullopt;
    const int rows = term.factor->num_residuals();
    const double s = Eigen::Map<const Eigen::VectorXd>(r.data(), rows).squaredNorm();
    total += robustified(s, term.huber_delta)[0];
  }
  return total;
}

std::optional<PoseLeastSquares::NormalEquations> PoseLeastSquares::linearize(
    const SE3d& T_w_b) const {
  const PoseBlock block = toPoseBlock(T_w_b);
  const Eigen::Matrix<double, kPoseBlockSize, kPoseTangentSize> plus =
      posePlusJacobian(block.data());
  NormalEquations equations;
  for (const PoseTerm& term : terms_) {
    bool evaluated = false;
    switch (term.factor->num_residuals()) {  // fixed sizes: the common cases, at Eigen's speed
      case 2:
        evaluated = accumulate<2>(term, block, plus, equations);
        break;
      case 3:
        evaluated = accumulate<3>(term, block, plus, equations);
        break;
      default:
        evaluated = accumulate<Eigen::Dynamic>(term, block, plus, equations);
        break;
    }
    if (!evaluated) return std::nullopt;
  }
  return equations;
}

template <int Rows>
bool PoseLeastSquares::accumulate(
    const PoseTerm& term, const PoseBlock& block,
    const Eigen::Matrix<double, kPoseBlockSize, kPoseTangentSize>& plus,
    NormalEquations& equations) {
  constexpr int kMaxRows = Rows == Eigen::Dynamic ? kMaxPoseTermResiduals : Rows;
  using Residual = Eigen::Matrix<double, Rows, 1, 0, kMaxRows, 1>;
  using BlockJacobian =
      Eigen::Matrix<double, Rows, kPoseBlockSize, Eigen::RowMajor, kMaxRows, kPoseBlockSize>;
  const int rows = term.factor->num_residuals();
  Residual residual(rows);
  BlockJacobian J_block(rows, kPoseBlockSize);
  if (!evaluateTerm(term, block, residual.data(), J_block.data())) return false;
  const Eigen::Matrix<double, Rows, kPoseTangentSize, 0, kMaxRows, kPoseTangentSize> J =
      J_block * plus;
  const std::array<double, 3> rho = robustified(residual.squaredNorm(), term.huber_delta);
  equations.H.noalias() += rho[1] * J.transpose() * J;
  equations.g.noalias() += rho[1] * J.transpose() * residual;
  equations.cost += rho[0];
  return true;
}

SE3d PoseLeastSquares::solve(const SE3d& start) const {
  SE3d T_w_b = start;
  std::optional<NormalEquations> equations = linearize(T_w_b);
  double lambda = options_.initial_lambda;
  for (int iteration = 0; equations && iteration < options_.max_iterations; ++iteration) {
    if (equations->g.lpNorm<Eigen::Infinity>() <= options_.gradient_tolerance) break;
    const Vector6d step = dampedStep(equations->H, equations->g, lambda);
    if (!step.allFinite() || step.norm() <= options_.parameter_tolerance) break;
    const SE3d candidate = plusPose(T_w_b, step);
    const std::optional<double> candidate_cost = cost(candidate);
    if (!candidate_cost || *candidate_cost >= equations->cost) {
      lambda *= 10.0;  // rejected: a shorter, more gradient-like step next
      continue;
    }
    const bool converged =
        equations->cost - *candidate_cost <= options_.function_tolerance * equations->cost;
    T_w_b = candidate;
    lambda = std::max(lambda / 10.0, 1e-12);
    if (converged) break;
    equations = linearize(T_w_b);
  }
  return T_w_b;
}

}  // namespace superdyna::optim

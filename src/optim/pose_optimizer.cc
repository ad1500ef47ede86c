#include "superdyna/optim/pose_optimizer.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>

#include "superdyna/core/error.h"
#include "superdyna/optim/imu_factors.h"
#include "superdyna/optim/pose_least_squares.h"

namespace superdyna::optim {

namespace {

void requirePositive(double value, const char* option) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw OptionError(option, "must be a positive finite number");
  }
}

/// The prior's covariance; throws OptionError when the information is not SPD.
Eigen::Matrix<double, 6, 6> priorCovariance(const PosePrior& prior) {
  const Eigen::Matrix<double, 6, 6>& information = prior.information;
  const Eigen::LLT<Eigen::Matrix<double, 6, 6>> llt(information);
  if (!information.allFinite() || !information.isApprox(information.transpose()) ||
      llt.info() != Eigen::Success) {
    throw OptionError("pose_prior.information", "must be symmetric positive definite");
  }
  return llt.solve(Eigen::Matrix<double, 6, 6>::Identity());
}

}  // namespace

void PoseOptimizerOptions::validate() const {
  if (rounds < 1) throw OptionError("pose_optimizer.rounds", "must be >= 1");
  if (iterations_per_round < 1) {
    throw OptionError("pose_optimizer.iterations_per_round", "must be >= 1");
  }
  if (robust_rounds < 0 || robust_rounds > rounds) {
    throw OptionError("pose_optimizer.robust_rounds", "must be in [0, rounds]");
  }
  requirePositive(sigma0_px, "pose_optimizer.sigma0_px");
  if (!(scale_factor >= 1.0) || !std::isfinite(scale_factor)) {
    throw OptionError("pose_optimizer.scale_factor", "must be a finite number >= 1");
  }
  requirePositive(chi2_mono, "pose_optimizer.chi2_mono");
  requirePositive(chi2_stereo, "pose_optimizer.chi2_stereo");
  if (min_inliers < 0) throw OptionError("pose_optimizer.min_inliers", "must be >= 0");
}

PoseOptimizer::PoseOptimizer(PoseOptimizerOptions options) : options_(options) {
  options_.validate();
}

void PoseOptimizer::validateInputs(const std::vector<ReprojectionCamera>& cameras,
                                   const std::vector<PoseObservation>& observations) const {
  for (const ReprojectionCamera& camera : cameras)
    camera.validate();
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const PoseObservation& observation = observations[i];
    if (observation.camera < 0 || observation.camera >= static_cast<int>(cameras.size())) {
      throw std::invalid_argument("PoseOptimizer: observation " + std::to_string(i) +
                                  " names camera " + std::to_string(observation.camera) + " of " +
                                  std::to_string(cameras.size()));
    }
    if (observation.right_x && !(cameras[observation.camera].baseline_m > 0.0)) {
      throw std::invalid_argument("PoseOptimizer: observation " + std::to_string(i) +
                                  " is stereo but its camera has no baseline");
    }
  }
}

ceres::CostFunction* PoseOptimizer::newCostFunction(const PoseObservation& observation,
                                                    const ReprojectionCamera& camera) const {
  const double sigma_px =
      octaveSigmaPx(observation.octave, options_.sigma0_px, options_.scale_factor);
  if (observation.right_x) {
    const Eigen::Vector3d observed(observation.normalized.x(), observation.normalized.y(),
                                   *observation.right_x);
    return new StereoReprojectionFactor(observed, camera, sigma_px);
  }
  return new ReprojectionFactor(observation.normalized, camera, sigma_px);
}

double PoseOptimizer::chi2(const PoseObservation& observation, const ReprojectionCamera& camera,
                           const SE3d& T_w_b) const {
  const double sigma_px =
      octaveSigmaPx(observation.octave, options_.sigma0_px, options_.scale_factor);
  if (observation.right_x) {
    const Eigen::Vector3d observed(observation.normalized.x(), observation.normalized.y(),
                                   *observation.right_x);
    const auto r =
        StereoReprojectionFactor(observed, camera, sigma_px).residual(T_w_b, observation.p_w);
    return r ? r->squaredNorm() : std::numeric_limits<double>::infinity();
  }
  const auto r =
      ReprojectionFactor(observation.normalized, camera, sigma_px).residual(T_w_b, observation.p_w);
  return r ? r->squaredNorm() : std::numeric_limits<double>::infinity();
}

double PoseOptimizer::chi2Threshold(const PoseObservation& observation) const {
  return observation.right_x ? options_.chi2_stereo : options_.chi2_mono;
}

SE3d PoseOptimizer::optimizeOnce(const PoseOptimizationResult& current,
                                 const std::vector<ReprojectionCamera>& cameras,
                                 const std::vector<PoseObservation>& observations, bool robust,
                                 const std::optional<PosePrior>& prior) const {
  const SE3d& T_w_b = current.T_w_b;
  std::vector<std::unique_ptr<ceres::CostFunction>> factors;
  std::vector<PoseTerm> terms;
  for (std::size_t i = 0; i < observations.size(); ++i) {
    // A residual that cannot be evaluated at the start (behind the camera) is left out.
    if (!current.inliers[i] || !std::isfinite(current.chi2[i])) continue;
    const PoseObservation& observation = observations[i];
    factors.emplace_back(newCostFunction(observation, cameras[observation.camera]));
    const double huber_delta = robust ? std::sqrt(chi2Threshold(observation)) : 0.0;
    terms.push_back({factors.back().get(), observation.p_w.data(), huber_delta});
  }
  if (prior) {
    factors.push_back(std::make_unique<PosePriorFactor>(prior->T_w_b, priorCovariance(*prior)));
    terms.push_back({factors.back().get(), nullptr, 0.0});
  }
  if (terms.empty()) return T_w_b;
  PoseLeastSquaresOptions solver;
  solver.max_iterations = options_.iterations_per_round;
  return PoseLeastSquares(std::move(terms), solver).solve(T_w_b);
}

void PoseOptimizer::classify(const std::vector<ReprojectionCamera>& cameras,
                             const std::vector<PoseObservation>& observations,
                             PoseOptimizationResult& result) const {
  result.num_inliers = 0;
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const PoseObservation& observation = observations[i];
    result.chi2[i] = chi2(observation, cameras[observation.camera], result.T_w_b);
    result.inliers[i] = result.chi2[i] < chi2Threshold(observation);
    result.num_inliers += result.inliers[i] ? 1 : 0;
  }
}

PoseOptimizationResult PoseOptimizer::optimize(const SE3d& T_w_b_initial,
                                               const std::vector<ReprojectionCamera>& cameras,
                                               const std::vector<PoseObservation>& observations,
                                               const std::optional<PosePrior>& prior) const {
  validateInputs(cameras, observations);
  if (prior) priorCovariance(*prior);  // validates before any work

  PoseOptimizationResult result;
  result.T_w_b = T_w_b_initial;
  result.chi2.assign(observations.size(), 0.0);
  result.inliers.assign(observations.size(), false);

  // Start from every match that can be evaluated (in front of the camera).
  classify(cameras, observations, result);
  for (std::size_t i = 0; i < observations.size(); ++i) {
    result.inliers[i] = std::isfinite(result.chi2[i]);
  }
  for (int round = 0; round < options_.rounds; ++round) {
    const int usable =
        static_cast<int>(std::count(result.inliers.begin(), result.inliers.end(), true));
    if (usable < options_.min_inliers && !prior) break;
    const bool robust = round < options_.robust_rounds;
    result.T_w_b = optimizeOnce(result, cameras, observations, robust, prior);
    ++result.rounds_run;
    classify(cameras, observations, result);
  }
  // Without any round, report the chi^2 test at the initial pose.
  if (result.rounds_run == 0) classify(cameras, observations, result);
  result.success = result.num_inliers >= options_.min_inliers;
  return result;
}

}  // namespace superdyna::optim

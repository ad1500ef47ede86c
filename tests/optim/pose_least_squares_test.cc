#include "superdyna/optim/pose_least_squares.h"

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <memory>
#include <random>
#include <stdexcept>
#include <vector>

#include "superdyna/optim/imu_factors.h"
#include "superdyna/optim/reprojection_factor.h"
#include "superdyna/optim/se3_manifold.h"

namespace superdyna::optim {
namespace {

constexpr double kFocalPx = 450.0;

/// A frame's reprojection factors (a third stereo, a fifth gross outliers, 1 px noise) on
/// points seen by a rotated, offset stereo camera, and a pose prior; the terms reference them.
struct Problem {
  SE3d T_w_b_true;
  std::vector<Eigen::Vector3d> points;
  std::vector<std::unique_ptr<ceres::CostFunction>> factors;
  std::vector<double> huber_deltas;
};

Problem makeProblem(std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0), fraction(0.0, 1.0);
  std::uniform_real_distribution<double> depth_m(1.5, 20.0);
  std::normal_distribution<double> noise_px(0.0, 1.0);
  ReprojectionCamera camera;
  camera.T_b_c =
      SE3d(expSO3(Eigen::Vector3d(0.02, -0.03, 1.56)), Eigen::Vector3d(-0.02, -0.06, 0.01));
  camera.fx = camera.fy = kFocalPx;
  camera.baseline_m = 0.11;
  Problem problem;
  problem.T_w_b_true = SE3d(expSO3(Eigen::Vector3d(0.3, -0.2, 0.9)), Eigen::Vector3d(1, 2, 0.5));
  problem.points.reserve(150);  // the terms point into it
  for (int i = 0; i < 150; ++i) {
    const Eigen::Vector3d p_c = depth_m(rng) * Eigen::Vector3d(0.8 * unit(rng), 0.6 * unit(rng), 1);
    problem.points.push_back(problem.T_w_b_true * (camera.T_b_c * p_c));
    const bool outlier = fraction(rng) < 0.2;
    const double shift = outlier ? 40.0 / kFocalPx : 0.0;
    const Eigen::Vector2d observed(p_c.x() / p_c.z() + shift + noise_px(rng) / kFocalPx,
                                   p_c.y() / p_c.z() - shift + noise_px(rng) / kFocalPx);
    const double sigma_px = 1.0 + (i % 3) * 0.2;
    if (fraction(rng) < 1.0 / 3.0) {
      const double right = (p_c.x() - camera.baseline_m) / p_c.z() + noise_px(rng) / kFocalPx;
      problem.factors.push_back(std::make_unique<StereoReprojectionFactor>(
          Eigen::Vector3d(observed.x(), observed.y(), right), camera, sigma_px));
      problem.huber_deltas.push_back(std::sqrt(kChi2Stereo95));
    } else {
      problem.factors.push_back(std::make_unique<ReprojectionFactor>(observed, camera, sigma_px));
      problem.huber_deltas.push_back(std::sqrt(kChi2Mono95));
    }
  }
  const SE3d T_w_prior(expSO3(Eigen::Vector3d(0.01, 0, -0.01)) * problem.T_w_b_true.rotation(),
                       problem.T_w_b_true.t + Eigen::Vector3d(0.01, -0.02, 0.0));
  problem.factors.push_back(std::make_unique<PosePriorFactor>(T_w_prior, 0.02, 0.05));
  problem.huber_deltas.push_back(0.0);
  return problem;
}

std::vector<PoseTerm> termsOf(const Problem& problem) {
  std::vector<PoseTerm> terms;
  for (std::size_t i = 0; i < problem.factors.size(); ++i) {
    const double* point = i < problem.points.size() ? problem.points[i].data() : nullptr;
    terms.push_back({problem.factors[i].get(), point, problem.huber_deltas[i]});
  }
  return terms;
}

/// The same problem solved by Ceres to convergence: the reference.
SE3d solveWithCeres(const Problem& problem, const SE3d& start) {
  PoseBlock pose = toPoseBlock(start);
  std::vector<Eigen::Vector3d> points = problem.points;
  ceres::Problem::Options options;
  options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem ceres_problem(options);
  ceres_problem.AddParameterBlock(pose.data(), kPoseBlockSize, new SE3Manifold());
  for (std::size_t i = 0; i < problem.factors.size(); ++i) {
    const double delta = problem.huber_deltas[i];
    ceres::LossFunction* loss = delta > 0.0 ? new ceres::HuberLoss(delta) : nullptr;
    if (i < points.size()) {
      ceres_problem.AddParameterBlock(points[i].data(), 3);
      ceres_problem.SetParameterBlockConstant(points[i].data());
      ceres_problem.AddResidualBlock(problem.factors[i].get(), loss, pose.data(), points[i].data());
    } else {
      ceres_problem.AddResidualBlock(problem.factors[i].get(), loss, pose.data());
    }
  }
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.max_num_iterations = 200;
  solver.function_tolerance = 1e-14;
  solver.gradient_tolerance = 1e-16;
  solver.parameter_tolerance = 1e-14;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &ceres_problem, &summary);
  EXPECT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();
  return fromPoseBlock(pose.data());
}

TEST(PoseLeastSquaresTest, ReachesTheMinimumCeresFindsForTheSameRobustProblem) {
  for (unsigned seed = 1; seed <= 5; ++seed) {
    std::mt19937 rng(seed);
    const Problem problem = makeProblem(rng);
    const SE3d start(expSO3(Eigen::Vector3d(0.02, 0.03, -0.02)) * problem.T_w_b_true.rotation(),
                     problem.T_w_b_true.t + Eigen::Vector3d(0.05, -0.04, 0.03));
    const SE3d reference = solveWithCeres(problem, start);
    PoseLeastSquaresOptions options;
    options.max_iterations = 100;
    options.function_tolerance = 1e-14;
    options.parameter_tolerance = 1e-14;
    options.gradient_tolerance = 1e-16;
    const PoseLeastSquares solver(termsOf(problem), options);
    const SE3d ours = solver.solve(start);
    SCOPED_TRACE(seed);
    EXPECT_LT((ours.t - reference.t).norm(), 1e-8);
    EXPECT_LT(rotationAngle(ours.rotation().transpose() * reference.rotation()), 1e-8);
    EXPECT_LT(*solver.cost(ours), *solver.cost(start));
    // Away from the truth by what the outliers' remaining pull and the prior allow.
    EXPECT_LT((ours.t - problem.T_w_b_true.t).norm(), 0.01);
  }
}

TEST(PoseLeastSquaresTest, TheHuberLossIsWhatCeresHuberLossComputes) {
  std::mt19937 rng(3);
  const Problem problem = makeProblem(rng);
  const std::vector<PoseTerm> terms = termsOf(problem);
  const SE3d at = problem.T_w_b_true;
  const PoseBlock block = toPoseBlock(at);
  double expected = 0.0;
  for (const PoseTerm& term : terms) {
    const double* parameters[2] = {block.data(), term.point};
    double r[6];
    ASSERT_TRUE(term.factor->Evaluate(parameters, r, nullptr));
    double s = 0.0;
    for (int k = 0; k < term.factor->num_residuals(); ++k)
      s += r[k] * r[k];
    double rho[3] = {s, 1.0, 0.0};
    if (term.huber_delta > 0.0) ceres::HuberLoss(term.huber_delta).Evaluate(s, rho);
    expected += rho[0];
  }
  EXPECT_NEAR(*PoseLeastSquares(terms).cost(at), expected, 1e-9 * expected);
}

TEST(PoseLeastSquaresTest, AResidualThatCannotBeEvaluatedAtTheStartLeavesTheStart) {
  std::mt19937 rng(4);
  Problem problem = makeProblem(rng);
  // A point behind the camera: the reprojection factor refuses to evaluate.
  const SE3d T_w_c = problem.T_w_b_true * SE3d(expSO3(Eigen::Vector3d(0.02, -0.03, 1.56)),
                                               Eigen::Vector3d(-0.02, -0.06, 0.01));
  problem.points[0] = T_w_c * Eigen::Vector3d(0.0, 0.0, -3.0);
  const PoseLeastSquares solver(termsOf(problem));
  const SE3d start(problem.T_w_b_true.rotation(),
                   problem.T_w_b_true.t + Eigen::Vector3d(0.1, 0, 0));
  EXPECT_FALSE(solver.cost(start).has_value());
  const SE3d out = solver.solve(start);
  EXPECT_EQ(out.t, start.t);
}

TEST(PoseLeastSquaresTest, RejectsAMissingCostFunction) {
  EXPECT_THROW(PoseLeastSquares({PoseTerm{}}), std::invalid_argument);
}

}  // namespace
}  // namespace superdyna::optim

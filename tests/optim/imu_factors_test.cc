#include "superdyna/optim/imu_factors.h"

#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>
#include <random>
#include <vector>

#include "imu/imu_test_motion.h"
#include "superdyna/core/error.h"

namespace superdyna::optim {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
constexpr TimeNs kSampleNs = 5'000'000;  // 200 Hz
using test::kMotionStartNs;

// ---------------------------------------------------------------------------------------------
// Helpers

/// A preintegration of the simulated IMU over [t_i, t_j], linearised at `bias`, with the noise
/// model of the EuRoC IMU (the simulator's default).
imu::Preintegration preintegrate(const sim::Se3Spline& motion, const sim::ImuNoiseOptions& o,
                                 TimeNs t_i, TimeNs t_j, const imu::Bias& bias) {
  const sim::ImuSequence seq = sim::ImuSimulator(o).simulate(motion, {t_i, t_j + kSampleNs});
  imu::Preintegration pre(bias, test::noiseOf(sim::ImuNoiseOptions{}));
  pre.integrateBetween(test::toImuSamples(seq.measurements), t_i, t_j);
  return pre;
}

imu::Bias simBias(const sim::ImuNoiseOptions& o) {
  return {o.initial_gyroscope_bias, o.initial_accelerometer_bias};
}

class Random {
 public:
  explicit Random(unsigned seed) : rng_(seed) {}
  Eigen::Vector3d vector(double scale) {
    const double x = u_(rng_), y = u_(rng_), z = u_(rng_);
    return scale * Eigen::Vector3d(x, y, z);
  }

 private:
  std::mt19937 rng_;
  std::uniform_real_distribution<double> u_{-1.0, 1.0};
};

/// Ambient Jacobians of a cost function by central differences of its residual (the pose
/// quaternion is perturbed coefficient by coefficient; the residuals normalise it).
std::vector<Eigen::MatrixXd> numericAmbientJacobians(const ceres::CostFunction& cost,
                                                     std::vector<std::vector<double>> blocks) {
  const int rows = cost.num_residuals();
  const auto evaluate = [&](const std::vector<std::vector<double>>& values) -> Eigen::VectorXd {
    std::vector<const double*> pointers;
    for (const auto& b : values)
      pointers.push_back(b.data());
    Eigen::VectorXd r(rows);
    EXPECT_TRUE(cost.Evaluate(pointers.data(), r.data(), nullptr));
    return r;
  };
  std::vector<Eigen::MatrixXd> out;
  const double h = 1e-6;
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    Eigen::MatrixXd J(rows, static_cast<int>(blocks[b].size()));
    for (std::size_t k = 0; k < blocks[b].size(); ++k) {
      auto plus = blocks, minus = blocks;
      plus[b][k] += h;
      minus[b][k] -= h;
      J.col(static_cast<int>(k)) = (evaluate(plus) - evaluate(minus)) / (2.0 * h);
    }
    out.push_back(J);
  }
  return out;
}

/// The cost function's own (ambient) Jacobians.
std::vector<Eigen::MatrixXd> analyticJacobians(const ceres::CostFunction& cost,
                                               const std::vector<std::vector<double>>& blocks) {
  const int rows = cost.num_residuals();
  std::vector<const double*> pointers;
  std::vector<std::vector<double>> storage;
  for (const auto& b : blocks) {
    pointers.push_back(b.data());
    storage.emplace_back(rows * b.size());
  }
  std::vector<double*> jacobians;
  for (auto& s : storage)
    jacobians.push_back(s.data());
  Eigen::VectorXd r(rows);
  EXPECT_TRUE(cost.Evaluate(pointers.data(), r.data(), jacobians.data()));
  std::vector<Eigen::MatrixXd> out;
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    const int cols = static_cast<int>(blocks[b].size());
    out.push_back(
        Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
            storage[b].data(), rows, cols));
  }
  return out;
}

/// Worst relative difference between analytic and numeric ambient Jacobians (relative to the
/// largest entry of each block).
double worstAmbientError(const ceres::CostFunction& cost,
                         const std::vector<std::vector<double>>& blocks) {
  const auto analytic = analyticJacobians(cost, blocks);
  const auto numeric = numericAmbientJacobians(cost, blocks);
  double worst = 0.0;
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    const double scale = std::max(numeric[b].cwiseAbs().maxCoeff(), 1e-12);
    worst = std::max(worst, (analytic[b] - numeric[b]).cwiseAbs().maxCoeff() / scale);
  }
  return worst;
}

/// Probes the tangent-space Jacobians with ceres::GradientChecker; returns the worst relative
/// error it found.
double gradientCheck(const ceres::CostFunction& cost,
                     const std::vector<std::vector<double>>& blocks,
                     const std::vector<const ceres::Manifold*>& manifolds) {
  ceres::NumericDiffOptions numeric_options;
  ceres::GradientChecker checker(&cost, &manifolds, numeric_options);
  std::vector<const double*> pointers;
  for (const auto& b : blocks)
    pointers.push_back(b.data());
  ceres::GradientChecker::ProbeResults results;
  const bool ok = checker.Probe(pointers.data(), 1e-6, &results);
  EXPECT_TRUE(ok) << results.error_log;
  return results.maximum_relative_error;
}

std::vector<double> toVector(const double* data, int size) {
  return std::vector<double>(data, data + size);
}

/// A random state near a reference (rotation up to ~0.4 rad off etc.).
ImuStateParameters randomState(Random& random, const imu::NavState& reference) {
  imu::NavState state = reference;
  state.R_w_b = reference.R_w_b * expSO3(random.vector(0.4));
  state.p_w += random.vector(0.3);
  state.v_w += random.vector(0.5);
  const imu::Bias bias{random.vector(0.05), random.vector(0.3)};
  ImuStateParameters params = ImuStateParameters::from(state, bias);
  // A quaternion slightly off unit length, as it may be between Ceres steps.
  for (int k = 0; k < 4; ++k)
    params.pose[k] *= 1.0 + 1e-3;
  return params;
}

struct Fixture {
  sim::Se3Spline motion = test::livelyMotion(2.0);
  sim::ImuNoiseOptions options;
  TimeNs t_i = kMotionStartNs + 300'000'000;
  TimeNs t_j = t_i + 100 * kSampleNs;  // 0.5 s

  Fixture() { options.noise = false; }
};

// ---------------------------------------------------------------------------------------------
// ImuPreintegrationFactor

TEST(ImuPreintegrationFactorTest, JacobiansMatchNumericDifferencesAtRandomStates) {
  Fixture f;
  f.options.noise = true;
  const imu::Preintegration pre =
      preintegrate(f.motion, f.options, f.t_i, f.t_j, simBias(f.options));
  const ImuPreintegrationFactor factor(pre);
  const SE3Manifold pose_manifold;
  const std::vector<const ceres::Manifold*> manifolds = {&pose_manifold, nullptr,        nullptr,
                                                         nullptr,        &pose_manifold, nullptr};
  Random random(3);
  double worst_tangent = 0.0, worst_ambient = 0.0, largest_rotation_residual = 0.0;
  for (int trial = 0; trial < 20; ++trial) {
    ImuStateParameters i = randomState(random, test::navStateAt(f.motion, f.t_i));
    ImuStateParameters j = randomState(random, test::navStateAt(f.motion, f.t_j));
    const std::vector<std::vector<double>> blocks = {
        toVector(i.pose.data(), 7),      toVector(i.velocity.data(), 3),
        toVector(i.bias_gyro.data(), 3), toVector(i.bias_acc.data(), 3),
        toVector(j.pose.data(), 7),      toVector(j.velocity.data(), 3)};
    worst_tangent = std::max(worst_tangent, gradientCheck(factor, blocks, manifolds));
    worst_ambient = std::max(worst_ambient, worstAmbientError(factor, blocks));
    const auto r = factor.unwhitenedResidual(i.navState(), i.bias(), j.navState());
    largest_rotation_residual = std::max(largest_rotation_residual, r.head<3>().norm());
  }
  std::cout << "[ ImuPreintegrationFactor, 20 random states (rotation residual up to "
            << largest_rotation_residual * kRadToDeg << " deg) ] worst relative Jacobian error: "
            << "tangent (GradientChecker) " << worst_tangent << ", ambient " << worst_ambient
            << "\n";
  EXPECT_LT(worst_tangent, 1e-6);
  EXPECT_LT(worst_ambient, 1e-6);
}

TEST(ImuPreintegrationFactorTest, ResidualVanishesAtGroundTruth) {
  Fixture f;  // exact IMU
  const imu::Bias truth_bias = simBias(f.options);
  const imu::NavState state_i = test::navStateAt(f.motion, f.t_i);
  const imu::NavState state_j = test::navStateAt(f.motion, f.t_j);

  // Linearised at the true bias.
  const ImuPreintegrationFactor at_truth(
      preintegrate(f.motion, f.options, f.t_i, f.t_j, truth_bias));
  const auto r = at_truth.unwhitenedResidual(state_i, truth_bias, state_j);
  ImuStateParameters i = ImuStateParameters::from(state_i, truth_bias);
  ImuStateParameters j = ImuStateParameters::from(state_j, truth_bias);
  const double* blocks[] = {i.pose.data(),     i.velocity.data(), i.bias_gyro.data(),
                            i.bias_acc.data(), j.pose.data(),     j.velocity.data()};
  Eigen::Matrix<double, 9, 1> whitened;
  ASSERT_TRUE(at_truth.Evaluate(blocks, whitened.data(), nullptr));
  std::cout << "[ residual at ground truth, 0.5 s, exact IMU ] rotation "
            << r.head<3>().norm() * kRadToDeg << " deg, velocity " << r.segment<3>(3).norm()
            << " m/s, position " << r.tail<3>().norm() << " m; whitened norm " << whitened.norm()
            << "\n";
  EXPECT_LT(r.head<3>().norm(), 1e-6);
  EXPECT_LT(r.segment<3>(3).norm(), 5e-5);
  EXPECT_LT(r.tail<3>().norm(), 1e-5);
  EXPECT_LT(whitened.norm(), 0.1);  // far below the unit noise level

  // Linearised at zero bias, evaluated at the true bias: the first-order correction.
  const ImuPreintegrationFactor at_zero(
      preintegrate(f.motion, f.options, f.t_i, f.t_j, imu::Bias{}));
  const auto r0 = at_zero.unwhitenedResidual(state_i, truth_bias, state_j);
  std::cout << "  linearised at zero bias (|bg| " << truth_bias.bg.norm() << " rad/s, |ba| "
            << truth_bias.ba.norm() << " m/s^2 away): rotation " << r0.head<3>().norm() * kRadToDeg
            << " deg, velocity " << r0.segment<3>(3).norm() << " m/s, position "
            << r0.tail<3>().norm() << " m\n";
  EXPECT_LT(r0.head<3>().norm(), 1e-4);
  EXPECT_LT(r0.segment<3>(3).norm(), 2e-3);
  EXPECT_LT(r0.tail<3>().norm(), 5e-4);
}

// With a noisy IMU and the true states, the whitened residual has unit covariance.
TEST(ImuPreintegrationFactorTest, WhitenedResidualHasUnitCovariance) {
  Fixture f;
  f.options.noise = true;
  f.options.gyroscope_random_walk = 0.0;  // the preintegration models the white noise
  f.options.accelerometer_random_walk = 0.0;
  const imu::Bias truth_bias = simBias(f.options);
  ImuStateParameters i = ImuStateParameters::from(test::navStateAt(f.motion, f.t_i), truth_bias);
  ImuStateParameters j = ImuStateParameters::from(test::navStateAt(f.motion, f.t_j), truth_bias);
  const double* blocks[] = {i.pose.data(),     i.velocity.data(), i.bias_gyro.data(),
                            i.bias_acc.data(), j.pose.data(),     j.velocity.data()};
  constexpr int kRuns = 3000;
  imu::Matrix9d second_moment = imu::Matrix9d::Zero();
  for (int run = 0; run < kRuns; ++run) {
    f.options.seed = 500 + static_cast<std::uint64_t>(run);
    const imu::Preintegration pre = preintegrate(f.motion, f.options, f.t_i, f.t_j, truth_bias);
    // The white noise of the factor's model is that of the simulated IMU.
    const ImuPreintegrationFactor factor(pre);
    Eigen::Matrix<double, 9, 1> r;
    ASSERT_TRUE(factor.Evaluate(blocks, r.data(), nullptr));
    second_moment += r * r.transpose() / kRuns;
  }
  const double worst_diagonal = (second_moment.diagonal().array() - 1.0).abs().maxCoeff();
  const double worst_off_diagonal =
      (second_moment - imu::Matrix9d::Identity()).cwiseAbs().maxCoeff();
  std::cout << "[ whitened residual over " << kRuns << " noisy runs ] E[r r^T] diagonal "
            << second_moment.diagonal().transpose() << "; worst |E[r r^T] - I| "
            << worst_off_diagonal << ", E|r|^2 " << second_moment.trace() << " (expected 9)\n";
  EXPECT_LT(worst_diagonal, 0.10);
  EXPECT_LT(worst_off_diagonal, 0.10);
  EXPECT_NEAR(second_moment.trace(), 9.0, 0.45);
}

TEST(ImuPreintegrationFactorTest, RejectsEmptyPreintegration) {
  EXPECT_THROW(ImuPreintegrationFactor(imu::Preintegration(imu::Bias{}, imu::ImuNoise{})),
               OptionError);
}

// ---------------------------------------------------------------------------------------------
// Bias random walk and priors

TEST(BiasRandomWalkFactorTest, WhiteningAndJacobians) {
  const imu::ImuNoise noise;
  const double dt = 0.25;
  const BiasRandomWalkFactor factor(noise, dt);
  // A change of one standard deviation on each axis gives a residual of one.
  const double sg = noise.gyro_random_walk * std::sqrt(dt);
  const double sa = noise.accel_random_walk * std::sqrt(dt);
  const std::vector<std::vector<double>> blocks = {{0.01, -0.02, 0.03},
                                                   {0.1, 0.2, -0.3},
                                                   {0.01 + sg, -0.02 - sg, 0.03},
                                                   {0.1, 0.2 + 2 * sa, -0.3}};
  const double* pointers[] = {blocks[0].data(), blocks[1].data(), blocks[2].data(),
                              blocks[3].data()};
  Eigen::Matrix<double, 6, 1> r;
  ASSERT_TRUE(factor.Evaluate(pointers, r.data(), nullptr));
  Eigen::Matrix<double, 6, 1> expected;
  expected << 1.0, -1.0, 0.0, 0.0, 2.0, 0.0;
  EXPECT_LT((r - expected).norm(), 1e-9);
  EXPECT_LT(worstAmbientError(factor, blocks), 1e-8);
  EXPECT_THROW(BiasRandomWalkFactor(noise, 0.0), OptionError);
}

// The simulator's bias random walk, whitened by the factor, has unit variance.
TEST(BiasRandomWalkFactorTest, WhitensSimulatedRandomWalk) {
  const sim::Se3Spline motion = test::livelyMotion(2.0);
  sim::ImuNoiseOptions options;  // EuRoC random walks
  const TimeNs t_0 = kMotionStartNs + 100'000'000;
  const int kIntervalSamples = 60;  // 0.3 s
  const double dt = kIntervalSamples * nsToSeconds(kSampleNs);
  const BiasRandomWalkFactor factor(test::noiseOf(options), dt);
  constexpr int kRuns = 400;
  Eigen::Matrix<double, 6, 1> second_moment = Eigen::Matrix<double, 6, 1>::Zero();
  int count = 0;
  for (int run = 0; run < kRuns; ++run) {
    options.seed = 77 + static_cast<std::uint64_t>(run);
    const sim::ImuSequence seq =
        sim::ImuSimulator(options).simulate(motion, {t_0, t_0 + 3 * kIntervalSamples * kSampleNs});
    for (int k = 0; k + kIntervalSamples < static_cast<int>(seq.states.size());
         k += kIntervalSamples) {
      const sim::ImuState& a = seq.states[k];
      const sim::ImuState& b = seq.states[k + kIntervalSamples];
      const double* pointers[] = {a.bg.data(), a.ba.data(), b.bg.data(), b.ba.data()};
      Eigen::Matrix<double, 6, 1> r;
      ASSERT_TRUE(factor.Evaluate(pointers, r.data(), nullptr));
      second_moment += r.cwiseProduct(r);
      ++count;
    }
  }
  second_moment /= count;
  std::cout << "[ bias random walk, " << count << " simulated intervals of " << dt
            << " s ] whitened variances " << second_moment.transpose() << "\n";
  for (int k = 0; k < 6; ++k)
    EXPECT_NEAR(second_moment[k], 1.0, 0.1);
}

TEST(PriorFactorTest, VectorAndPosePriorsWhitenAndDifferentiate) {
  Eigen::Matrix3d covariance;
  covariance << 0.04, 0.01, 0.0, 0.01, 0.09, 0.0, 0.0, 0.0, 0.01;
  const Vector3PriorFactor vector_prior(Eigen::Vector3d(1.0, 2.0, 3.0), covariance);
  const std::vector<std::vector<double>> x = {{1.3, 1.5, 3.2}};
  EXPECT_LT(worstAmbientError(vector_prior, x), 1e-8);
  Eigen::Vector3d r;
  const double* px[] = {x[0].data()};
  ASSERT_TRUE(vector_prior.Evaluate(px, r.data(), nullptr));
  const Eigen::Vector3d e(0.3, -0.5, 0.2);
  EXPECT_NEAR(r.squaredNorm(), e.dot(covariance.inverse() * e), 1e-12);
  EXPECT_THROW(Vector3PriorFactor(Eigen::Vector3d::Zero(), 0.0), OptionError);

  const SE3d prior(expSO3(Eigen::Vector3d(0.3, -0.2, 0.9)), Eigen::Vector3d(1.0, -2.0, 0.5));
  const PosePriorFactor pose_prior(prior, 0.01, 0.05);
  const SE3Manifold pose_manifold;
  const std::vector<const ceres::Manifold*> manifolds = {&pose_manifold};
  Random random(9);
  for (int trial = 0; trial < 10; ++trial) {
    const SE3d pose(prior.rotation() * expSO3(random.vector(0.5)), prior.t + random.vector(1.0));
    const auto p = toPoseBlock(pose);
    const std::vector<std::vector<double>> blocks = {toVector(p.data(), 7)};
    EXPECT_LT(gradientCheck(pose_prior, blocks, manifolds), 1e-6);
    EXPECT_LT(worstAmbientError(pose_prior, blocks), 1e-6);
  }
  // One standard deviation of rotation about the body x axis gives a residual of one.
  const auto p = toPoseBlock(SE3d(prior.rotation() * expSO3(Eigen::Vector3d(0.01, 0, 0)),
                                  prior.t + Eigen::Vector3d(0, 0, 0.1)));
  const double* pp[] = {p.data()};
  Eigen::Matrix<double, 6, 1> r6;
  ASSERT_TRUE(pose_prior.Evaluate(pp, r6.data(), nullptr));
  Eigen::Matrix<double, 6, 1> expected;
  expected << 1.0, 0.0, 0.0, 0.0, 0.0, 2.0;
  EXPECT_LT((r6 - expected).norm(), 1e-9);
}

TEST(PoseParametersTest, RoundTrip) {
  const SE3d pose(expSO3(Eigen::Vector3d(0.3, -0.2, 2.9)), Eigen::Vector3d(1.0, -2.0, 0.5));
  const auto p = toPoseBlock(pose);
  EXPECT_EQ(p[3], pose.q.normalized().w());  // Eigen order: x, y, z, w
  const SE3d back = fromPoseBlock(p.data());
  EXPECT_LT(rotationAngle(back.rotation().transpose() * pose.rotation()), 1e-15);
  EXPECT_LT((back.t - pose.t).norm(), 1e-15);
  const imu::NavState state{pose.rotation(), pose.t, Eigen::Vector3d(1, 2, 3)};
  const imu::Bias bias{Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d(-1, -2, -3)};
  const ImuStateParameters params = ImuStateParameters::from(state, bias);
  EXPECT_LT((params.navState().R_w_b - state.R_w_b).norm(), 1e-15);
  EXPECT_EQ(params.navState().v_w, state.v_w);
  EXPECT_EQ(params.bias().ba, bias.ba);
}

// ---------------------------------------------------------------------------------------------
// A small visual-inertial window through the problem helpers: pose priors stand in for vision.

TEST(ImuProblemTest, RecoversVelocitiesAndBiasesWithPosePriors) {
  const sim::Se3Spline motion = test::livelyMotion(3.5);
  sim::ImuNoiseOptions options;  // noisy EuRoC IMU
  const TimeNs t_0 = kMotionStartNs + 200'000'000;
  const TimeNs spacing = 250'000'000;
  constexpr int kStates = 12;  // 2.75 s
  const sim::ImuSequence seq =
      sim::ImuSimulator(options).simulate(motion, {t_0, t_0 + kStates * spacing});
  const std::vector<sensors::ImuSample> samples = test::toImuSamples(seq.measurements);

  std::vector<ImuStateParameters> states(kStates);
  std::vector<imu::NavState> truth;
  Random random(5);
  ceres::Problem problem;
  for (int k = 0; k < kStates; ++k) {
    const TimeNs t = t_0 + k * spacing;
    truth.push_back(test::navStateAt(motion, t));
    // Start from poses 2 cm / 1 deg off, zero velocity and zero biases.
    imu::NavState guess = truth.back();
    guess.R_w_b = guess.R_w_b * expSO3(random.vector(0.01));
    guess.p_w += random.vector(0.02);
    guess.v_w.setZero();
    states[k] = ImuStateParameters::from(guess, imu::Bias{});
    // "Vision": the true pose with 1 mm / 0.05 deg.
    problem.AddResidualBlock(
        new PosePriorFactor(SE3d(truth.back().R_w_b, truth.back().p_w), 0.05 / kRadToDeg, 0.001),
        nullptr, states[k].pose.data());
  }
  for (int k = 0; k + 1 < kStates; ++k) {
    imu::Preintegration pre(imu::Bias{}, test::noiseOf(options));
    pre.integrateBetween(samples, t_0 + k * spacing, t_0 + (k + 1) * spacing);
    const ImuEdge edge = addImuEdge(problem, pre, states[k].blocks(), states[k + 1].blocks());
    EXPECT_NE(edge.preintegration, nullptr);
    EXPECT_NE(edge.bias_random_walk, nullptr);
  }
  addBiasPrior(problem, states[0].blocks(), imu::Bias{}, 1.0, 1.0);
  EXPECT_EQ(problem.NumParameterBlocks(), 4 * kStates);
  EXPECT_EQ(problem.NumResidualBlocks(), kStates + 2 * (kStates - 1) + 2);
  EXPECT_TRUE(problem.HasManifold(states[0].pose.data()));

  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_SCHUR;
  solver_options.max_num_iterations = 50;
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
  EXPECT_EQ(summary.termination_type, ceres::CONVERGENCE) << summary.BriefReport();

  double worst_v = 0.0, worst_bg = 0.0, worst_ba = 0.0, worst_q_norm = 0.0;
  for (int k = 0; k < kStates; ++k) {
    worst_v = std::max(worst_v, (states[k].navState().v_w - truth[k].v_w).norm());
    worst_bg = std::max(worst_bg, (states[k].bias().bg - seq.states[k * 50].bg).norm());
    worst_ba = std::max(worst_ba, (states[k].bias().ba - seq.states[k * 50].ba).norm());
    worst_q_norm =
        std::max(worst_q_norm,
                 std::abs(Eigen::Map<const Eigen::Vector4d>(states[k].pose.data()).norm() - 1));
  }
  std::cout << "[ 12-state window, IMU + 1 mm / 0.05 deg pose priors ] " << summary.BriefReport()
            << "\n  worst velocity error " << worst_v << " m/s, gyro bias " << worst_bg
            << " rad/s, accel bias " << worst_ba << " m/s^2, |q| - 1 " << worst_q_norm << "\n";
  EXPECT_LT(worst_v, 0.02);
  EXPECT_LT(worst_bg, 2e-3);
  EXPECT_LT(worst_ba, 0.05);
  EXPECT_LT(worst_q_norm, 1e-12);
}

}  // namespace
}  // namespace superdyna::optim

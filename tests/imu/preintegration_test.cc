#include "superdyna/imu/preintegration.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include "imu/imu_test_motion.h"
#include "superdyna/core/error.h"

namespace superdyna::imu {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
constexpr TimeNs kSampleNs = 5'000'000;  // 200 Hz

using test::kMotionStartNs;

sim::ImuNoiseOptions exactImu() {
  sim::ImuNoiseOptions options;
  options.noise = false;
  return options;
}

Bias initialBias(const sim::ImuNoiseOptions& options) {
  return {options.initial_gyroscope_bias, options.initial_accelerometer_bias};
}

/// Samples of the exact IMU over [begin, end] of the motion.
std::vector<sensors::ImuSample> simulate(const sim::Se3Spline& motion,
                                         const sim::ImuNoiseOptions& o, TimeNs begin_ns,
                                         TimeNs end_ns) {
  return test::toImuSamples(sim::ImuSimulator(o).simulate(motion, {begin_ns, end_ns}).measurements);
}

/// World-frame strapdown integration with the same discretisation as the preintegration (mean of
/// consecutive samples, force rotated at mid-interval), written independently of it.
NavState strapdown(const NavState& start, const std::vector<sensors::ImuSample>& samples,
                   const Bias& bias) {
  NavState x = start;
  const Eigen::Vector3d g_w = gravityVector();
  for (std::size_t k = 0; k + 1 < samples.size(); ++k) {
    const double dt = nsToSeconds(samples[k + 1].t_ns - samples[k].t_ns);
    const Eigen::Vector3d w = 0.5 * (samples[k].gyro + samples[k + 1].gyro) - bias.bg;
    const Eigen::Vector3d f = 0.5 * (samples[k].accel + samples[k + 1].accel) - bias.ba;
    const Eigen::Vector3d a_w = x.R_w_b * expSO3(0.5 * dt * w) * f + g_w;
    x.p_w += x.v_w * dt + 0.5 * a_w * dt * dt;
    x.v_w += a_w * dt;
    x.R_w_b = x.R_w_b * expSO3(dt * w);
  }
  return x;
}

double angleDeg(const Eigen::Matrix3d& R_a, const Eigen::Matrix3d& R_b) {
  return rotationAngle(R_a.transpose() * R_b) * kRadToDeg;
}

TEST(ImuNoiseTest, FromCalibrationAndValidate) {
  sensors::ImuCalibration calibration;
  calibration.gyroscope_noise_density = 1e-4;
  calibration.gyroscope_random_walk = 2e-5;
  calibration.accelerometer_noise_density = 3e-3;
  calibration.accelerometer_random_walk = 4e-3;
  const ImuNoise noise = ImuNoise::fromCalibration(calibration);
  EXPECT_EQ(noise.gyro_noise_density, 1e-4);
  EXPECT_EQ(noise.gyro_random_walk, 2e-5);
  EXPECT_EQ(noise.accel_noise_density, 3e-3);
  EXPECT_EQ(noise.accel_random_walk, 4e-3);
  EXPECT_NO_THROW(noise.validate());
  ImuNoise bad = noise;
  bad.accel_random_walk = 0.0;
  EXPECT_THROW(bad.validate(), OptionError);
  EXPECT_THROW(Preintegration(Bias{}, bad), OptionError);
  const Matrix6d rw = biasRandomWalkCovariance(noise, 0.5);
  EXPECT_DOUBLE_EQ(rw(0, 0), 2e-5 * 2e-5 * 0.5);
  EXPECT_DOUBLE_EQ(rw(5, 5), 4e-3 * 4e-3 * 0.5);
  EXPECT_EQ(rw(0, 3), 0.0);
}

TEST(PreintegrationTest, EmptyAndInvalidSteps) {
  Preintegration pre(Bias{}, ImuNoise{});
  EXPECT_EQ(pre.deltaTime(), 0.0);
  EXPECT_TRUE(pre.deltaRotation().isIdentity());
  EXPECT_THROW(pre.integrate(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 0.0), OptionError);
  EXPECT_THROW(pre.integrate(Eigen::Vector3d::Constant(NAN), Eigen::Vector3d::Zero(), 0.01),
               OptionError);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  const std::vector<sensors::ImuSample> samples = {{0, zero, zero}, {10, zero, zero}};
  EXPECT_THROW(pre.integrateBetween(samples, 5, 5), OptionError);
  EXPECT_THROW(pre.integrateBetween({}, 0, 5), OptionError);
  const std::vector<sensors::ImuSample> unordered = {{10, zero, zero}, {0, zero, zero}};
  EXPECT_THROW(pre.integrateBetween(unordered, 0, 5), OptionError);
  EXPECT_TRUE(pre.steps().empty());
}

// Body-frame preintegration plus predict() equals integrating the same samples in the world frame.
TEST(PreintegrationTest, EqualsDirectIntegrationOfExactImu) {
  const sim::Se3Spline motion = test::livelyMotion(2.0);
  const sim::ImuNoiseOptions options = exactImu();
  const TimeNs t_i = kMotionStartNs + 300'000'000;  // +0.3 s
  const TimeNs t_j = t_i + 100 * kSampleNs;         // 0.5 s later
  const std::vector<sensors::ImuSample> samples = simulate(motion, options, t_i, t_j);
  ASSERT_EQ(samples.size(), 101u);

  const Bias bias = initialBias(options);
  Preintegration pre(bias, test::noiseOf(options));
  pre.integrateBetween(samples, t_i, t_j);
  EXPECT_NEAR(pre.deltaTime(), 0.5, 1e-12);
  EXPECT_EQ(pre.steps().size(), 100u);

  const NavState state_i = test::navStateAt(motion, t_i);
  const NavState direct = strapdown(state_i, samples, bias);
  const Eigen::Matrix3d& R_w_i = state_i.R_w_b;
  const double dt = pre.deltaTime();
  const Eigen::Vector3d g_w = gravityVector();
  // The deltas the world-frame integration implies.
  const Eigen::Matrix3d dR = R_w_i.transpose() * direct.R_w_b;
  const Eigen::Vector3d dV = R_w_i.transpose() * (direct.v_w - state_i.v_w - g_w * dt);
  const Eigen::Vector3d dP =
      R_w_i.transpose() * (direct.p_w - state_i.p_w - state_i.v_w * dt - 0.5 * g_w * dt * dt);
  const double err_R = rotationAngle(dR.transpose() * pre.deltaRotation());
  const double err_V = (dV - pre.deltaVelocity()).norm();
  const double err_P = (dP - pre.deltaPosition()).norm();
  std::cout << "[ preint vs direct ] dR " << err_R << " rad, dV " << err_V << " m/s, dP " << err_P
            << " m\n";
  EXPECT_LT(err_R, 1e-12);
  EXPECT_LT(err_V, 1e-12);
  EXPECT_LT(err_P, 1e-12);
}

// predict() from the true state i reaches the spline's state j: < 1 mm, < 0.01 deg over 0.5 s.
TEST(PreintegrationTest, PredictMatchesSplineGroundTruth) {
  const sim::Se3Spline motion = test::livelyMotion(3.0);
  const sim::ImuNoiseOptions options = exactImu();
  double worst_p = 0.0, worst_v = 0.0, worst_deg = 0.0;
  for (int start_ms : {100, 700, 1300, 2100}) {
    // Frame times between IMU samples: the ends are interpolated.
    const TimeNs t_i = kMotionStartNs + start_ms * 1'000'000 + 2'300'000;
    const TimeNs t_j = t_i + 500'000'000;
    const std::vector<sensors::ImuSample> samples =
        simulate(motion, options, kMotionStartNs + start_ms * 1'000'000, t_j + kSampleNs);
    Preintegration pre(initialBias(options), test::noiseOf(options));
    pre.integrateBetween(samples, t_i, t_j);
    ASSERT_NEAR(pre.deltaTime(), 0.5, 1e-12);
    const NavState predicted = pre.predict(test::navStateAt(motion, t_i), initialBias(options));
    const NavState truth = test::navStateAt(motion, t_j);
    worst_p = std::max(worst_p, (predicted.p_w - truth.p_w).norm());
    worst_v = std::max(worst_v, (predicted.v_w - truth.v_w).norm());
    worst_deg = std::max(worst_deg, angleDeg(predicted.R_w_b, truth.R_w_b));
  }
  std::cout << "[ predict vs spline, 0.5 s @ 200 Hz ] position " << worst_p * 1e3
            << " mm, velocity " << worst_v * 1e3 << " mm/s, rotation " << worst_deg << " deg\n";
  EXPECT_LT(worst_p, 1e-3);
  EXPECT_LT(worst_deg, 0.01);
  EXPECT_LT(worst_v, 5e-3);
}

// Splitting at a sample time: the two halves compose to the whole (bookkeeping of the ends).
TEST(PreintegrationTest, ComposesAtSampleTimeAndHoldsOutsideSamples) {
  const sim::Se3Spline motion = test::livelyMotion(2.0);
  const sim::ImuNoiseOptions options = exactImu();
  const TimeNs t_0 = kMotionStartNs + 200'000'000;
  const std::vector<sensors::ImuSample> samples =
      simulate(motion, options, t_0, t_0 + 80 * kSampleNs);
  const TimeNs t_i = t_0 + 1'000'000, t_m = t_0 + 40 * kSampleNs, t_j = t_0 + 77 * kSampleNs + 7;
  const Bias bias = initialBias(options);
  Preintegration whole(bias, ImuNoise{}), first(bias, ImuNoise{}), second(bias, ImuNoise{});
  whole.integrateBetween(samples, t_i, t_j);
  first.integrateBetween(samples, t_i, t_m);
  second.integrateBetween(samples, t_m, t_j);
  const double dt_2 = second.deltaTime();
  const Eigen::Matrix3d dR = first.deltaRotation() * second.deltaRotation();
  const Eigen::Vector3d dV = first.deltaVelocity() + first.deltaRotation() * second.deltaVelocity();
  const Eigen::Vector3d dP = first.deltaPosition() + first.deltaVelocity() * dt_2 +
                             first.deltaRotation() * second.deltaPosition();
  EXPECT_NEAR(whole.deltaTime(), first.deltaTime() + dt_2, 1e-15);
  EXPECT_LT(rotationAngle(dR.transpose() * whole.deltaRotation()), 1e-13);
  EXPECT_LT((dV - whole.deltaVelocity()).norm(), 1e-13);
  EXPECT_LT((dP - whole.deltaPosition()).norm(), 1e-13);

  // Outside the samples the nearest one is held: one sample at 0 means a constant signal.
  const std::vector<sensors::ImuSample> one = {
      {0, Eigen::Vector3d(0.0, 0.0, 0.5), Eigen::Vector3d::Zero()}};
  Preintegration held(Bias{}, ImuNoise{});
  held.integrateBetween(one, -100'000'000, 300'000'000);
  EXPECT_NEAR(held.deltaTime(), 0.4, 1e-15);
  EXPECT_LT((logSO3(held.deltaRotation()) - Eigen::Vector3d(0.0, 0.0, 0.2)).norm(), 1e-14);
}

// Bias Jacobians equal central differences of re-integration at a perturbed linearisation bias.
TEST(PreintegrationTest, BiasJacobiansMatchFiniteDifferences) {
  const sim::Se3Spline motion = test::livelyMotion(2.0);
  sim::ImuNoiseOptions options;  // noise on: arbitrary realistic measurements
  const TimeNs t_i = kMotionStartNs + 100'000'000;
  const std::vector<sensors::ImuSample> samples =
      simulate(motion, options, t_i, t_i + 140 * kSampleNs);
  const Bias bias0{Eigen::Vector3d(0.01, -0.02, 0.05), Eigen::Vector3d(0.1, -0.05, 0.2)};
  Preintegration pre(bias0, test::noiseOf(options));
  pre.integrateBetween(samples, t_i + 1'234'567, t_i + 130 * kSampleNs + 3'000'000);

  const auto perturbed = [&](int k, double h) -> Preintegration {
    Preintegration copy = pre;
    Bias b = bias0;
    if (k < 3) {
      b.bg[k] += h;
    } else {
      b.ba[k - 3] += h;
    }
    copy.reintegrate(b);
    return copy;
  };
  Eigen::Matrix3d J_R_bg, J_V_bg, J_V_ba, J_P_bg, J_P_ba;
  for (int k = 0; k < 6; ++k) {
    const double h = 1e-6;
    const Preintegration plus = perturbed(k, h), minus = perturbed(k, -h);
    const Eigen::Vector3d d_phi =
        (logSO3(pre.deltaRotation().transpose() * plus.deltaRotation()) -
         logSO3(pre.deltaRotation().transpose() * minus.deltaRotation())) /
        (2.0 * h);
    const Eigen::Vector3d d_v = (plus.deltaVelocity() - minus.deltaVelocity()) / (2.0 * h);
    const Eigen::Vector3d d_p = (plus.deltaPosition() - minus.deltaPosition()) / (2.0 * h);
    if (k < 3) {
      J_R_bg.col(k) = d_phi;
      J_V_bg.col(k) = d_v;
      J_P_bg.col(k) = d_p;
    } else {
      EXPECT_LT(d_phi.norm(), 1e-9);  // the rotation does not depend on ba
      J_V_ba.col(k - 3) = d_v;
      J_P_ba.col(k - 3) = d_p;
    }
  }
  const auto rel = [](const Eigen::Matrix3d& numeric, const Eigen::Matrix3d& analytic) -> double {
    return (numeric - analytic).norm() / analytic.norm();
  };
  std::cout << "[ bias Jacobians, relative error vs central differences ] J_R_bg "
            << rel(J_R_bg, pre.J_R_bg()) << ", J_V_bg " << rel(J_V_bg, pre.J_V_bg()) << ", J_V_ba "
            << rel(J_V_ba, pre.J_V_ba()) << ", J_P_bg " << rel(J_P_bg, pre.J_P_bg()) << ", J_P_ba "
            << rel(J_P_ba, pre.J_P_ba()) << "\n";
  EXPECT_LT(rel(J_R_bg, pre.J_R_bg()), 1e-6);
  EXPECT_LT(rel(J_V_bg, pre.J_V_bg()), 1e-6);
  EXPECT_LT(rel(J_V_ba, pre.J_V_ba()), 1e-6);
  EXPECT_LT(rel(J_P_bg, pre.J_P_bg()), 1e-6);
  EXPECT_LT(rel(J_P_ba, pre.J_P_ba()), 1e-6);

  // The first-order correction to a moved bias versus re-integration: the error is of second
  // order (halving the bias change divides it by about 4).
  const auto correctionErrors = [&](double fraction) -> Eigen::Vector3d {
    Bias moved = bias0;
    moved.bg += fraction * Eigen::Vector3d(0.006, -0.008, 0.0);
    moved.ba += fraction * Eigen::Vector3d(0.0, 0.06, -0.08);
    Preintegration exact = pre;
    exact.reintegrate(moved);
    return {rotationAngle(exact.deltaRotation().transpose() * pre.correctedDeltaRotation(moved)),
            (exact.deltaVelocity() - pre.correctedDeltaVelocity(moved)).norm(),
            (exact.deltaPosition() - pre.correctedDeltaPosition(moved)).norm()};
  };
  const Eigen::Vector3d err = correctionErrors(1.0);
  const Eigen::Vector3d ratio = err.cwiseQuotient(correctionErrors(0.5));
  std::cout << "[ first-order bias correction, |dbg| 0.01 rad/s, |dba| 0.1 m/s^2, 0.65 s ] dR "
            << err[0] * kRadToDeg << " deg, dV " << err[1] << " m/s, dP " << err[2]
            << " m; error ratio for half the change " << ratio.transpose() << "\n";
  EXPECT_LT(err[0], 1e-5);  // rad
  EXPECT_LT(err[1], 5e-4);  // m/s
  EXPECT_LT(err[2], 1e-4);  // m
  for (int k = 0; k < 3; ++k) {
    EXPECT_GT(ratio[k], 3.5);
    EXPECT_LT(ratio[k], 4.5);
  }
  Bias moved = bias0;
  moved.bg += Eigen::Vector3d(0.006, -0.008, 0.0);
  Preintegration exact = pre;
  exact.reintegrate(moved);
  // Without the correction the errors would be about |J dbg|.
  EXPECT_GT(rotationAngle(exact.deltaRotation().transpose() * pre.deltaRotation()), 100 * err[0]);
}

TEST(PreintegrationTest, ReintegratesOnlyWhenTheBiasMovedFar) {
  const sim::Se3Spline motion = test::livelyMotion(2.0);
  const sim::ImuNoiseOptions options = exactImu();
  const TimeNs t_i = kMotionStartNs + 100'000'000;
  const std::vector<sensors::ImuSample> samples =
      simulate(motion, options, t_i, t_i + 60 * kSampleNs);
  Preintegration pre(Bias{}, ImuNoise{});
  pre.integrateBetween(samples, t_i, t_i + 60 * kSampleNs);
  const Eigen::Vector3d dV_before = pre.deltaVelocity();

  Bias near;
  near.bg = Eigen::Vector3d(0.005, 0.0, 0.0);
  EXPECT_FALSE(pre.reintegrateIfBiasMoved(near));
  EXPECT_EQ(pre.deltaVelocity(), dV_before);
  EXPECT_TRUE(pre.linearizationBias().bg.isZero());

  const Bias far = initialBias(options);
  EXPECT_TRUE(pre.reintegrateIfBiasMoved(far));
  EXPECT_EQ(pre.linearizationBias().bg, far.bg);
  Preintegration fresh(far, ImuNoise{});
  fresh.integrateBetween(samples, t_i, t_i + 60 * kSampleNs);
  EXPECT_LT((pre.deltaVelocity() - fresh.deltaVelocity()).norm(), 1e-15);
  EXPECT_LT((pre.deltaPosition() - fresh.deltaPosition()).norm(), 1e-15);
  EXPECT_LT((pre.covariance() - fresh.covariance()).norm(), 1e-20);
  EXPECT_LT((pre.J_P_bg() - fresh.J_P_bg()).norm(), 1e-15);
  ReintegrationOptions bad;
  bad.max_gyro_bias_change = -1.0;
  EXPECT_THROW(pre.reintegrateIfBiasMoved(far, bad), OptionError);
  EXPECT_THROW(pre.biasMovedBeyond(far, bad), OptionError);

  // Without its steps it keeps every result, and refuses to integrate further or again.
  const Preintegration kept = pre;
  pre.releaseSteps();
  EXPECT_TRUE(pre.steps().empty());
  EXPECT_EQ(pre.deltaVelocity(), kept.deltaVelocity());
  EXPECT_EQ(pre.covariance(), kept.covariance());
  EXPECT_EQ(pre.J_V_ba(), kept.J_V_ba());
  EXPECT_FALSE(pre.biasMovedBeyond(far));
  EXPECT_THROW(pre.reintegrate(near), std::logic_error);
  EXPECT_THROW(pre.integrate(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 0.01),
               std::logic_error);
}

// The propagated covariance against the scatter of 4000 noisy simulations (white noise only; the
// relative standard error of a variance estimate is then sqrt(2 / 4000) = 2.2 %).
TEST(PreintegrationTest, CovarianceMatchesMonteCarlo) {
  const sim::Se3Spline motion = test::livelyMotion(2.0);
  sim::ImuNoiseOptions options;
  options.gyroscope_random_walk = 0.0;  // constant biases: the covariance models white noise
  options.accelerometer_random_walk = 0.0;
  const TimeNs t_i = kMotionStartNs + 400'000'000;
  const TimeNs t_j = t_i + 100 * kSampleNs;  // 0.5 s at 200 Hz
  const Bias bias = initialBias(options);
  const ImuNoise noise = test::noiseOf(exactImu());

  sim::ImuNoiseOptions exact_options = options;
  exact_options.noise = false;
  Preintegration reference(bias, noise);
  reference.integrateBetween(simulate(motion, exact_options, t_i, t_j), t_i, t_j);

  constexpr int kRuns = 4000;
  std::vector<Eigen::Matrix<double, 9, 1>> errors;
  for (int run = 0; run < kRuns; ++run) {
    options.seed = 1000 + static_cast<std::uint64_t>(run);
    Preintegration pre(bias, noise);
    pre.integrateBetween(simulate(motion, options, t_i, t_j), t_i, t_j);
    Eigen::Matrix<double, 9, 1> e;
    e << logSO3(reference.deltaRotation().transpose() * pre.deltaRotation()),
        pre.deltaVelocity() - reference.deltaVelocity(),
        pre.deltaPosition() - reference.deltaPosition();
    errors.push_back(e);
  }
  Eigen::Matrix<double, 9, 1> mean = Eigen::Matrix<double, 9, 1>::Zero();
  for (const auto& e : errors)
    mean += e / kRuns;
  Matrix9d sample = Matrix9d::Zero();
  for (const auto& e : errors)
    sample += (e - mean) * (e - mean).transpose() / (kRuns - 1);

  const Matrix9d& predicted = reference.covariance();
  // Correlation-normalised difference: (C_mc - C) / sqrt(C_ii C_jj).
  const Eigen::Matrix<double, 9, 1> sigma = predicted.diagonal().cwiseSqrt();
  const Matrix9d normalised = (sample - predicted).cwiseQuotient(sigma * sigma.transpose());
  double worst_diag = 0.0;
  for (int k = 0; k < 9; ++k)
    worst_diag = std::max(worst_diag, std::abs(normalised(k, k)));
  const Matrix9d info = predicted.inverse();
  double mahalanobis = 0.0;
  for (const auto& e : errors)
    mahalanobis += e.dot(info * e) / kRuns;
  std::cout << "[ covariance vs Monte Carlo, " << kRuns << " runs ] sigma dphi "
            << sigma.head<3>().transpose() << " rad, dv " << sigma.segment<3>(3).transpose()
            << " m/s, dp " << sigma.tail<3>().transpose() << " m\n"
            << "  worst relative variance difference " << worst_diag
            << ", worst normalised covariance difference " << normalised.cwiseAbs().maxCoeff()
            << ", mean squared Mahalanobis distance " << mahalanobis << " (expected 9)\n"
            << "  variance ratios MC / predicted "
            << sample.diagonal().cwiseQuotient(predicted.diagonal()).transpose() << "\n";
  EXPECT_LT(worst_diag, 0.10);
  EXPECT_LT(normalised.cwiseAbs().maxCoeff(), 0.10);
  EXPECT_NEAR(mahalanobis, 9.0, 0.9);
  EXPECT_LT((mean.cwiseQuotient(sigma)).cwiseAbs().maxCoeff(), 0.15);  // unbiased
}

}  // namespace
}  // namespace superdyna::imu

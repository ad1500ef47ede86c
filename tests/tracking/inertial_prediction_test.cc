#include "superdyna/tracking/inertial_prediction.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <iostream>
#include <random>

#include "imu/imu_test_motion.h"
#include "superdyna/core/error.h"

namespace superdyna::tracking {
namespace {

using test::kMotionStartNs;

TEST(ImuSampleBuffer, HandsOverTheSamplesBracketingEachKeyFrameInterval) {
  ImuSampleBuffer buffer;
  const auto sample = [](TimeNs t) {
    sensors::ImuSample s;
    s.t_ns = t;
    s.gyro = Eigen::Vector3d(0.1, 0.0, 0.0);
    s.accel = Eigen::Vector3d(0.0, 0.0, 9.81);
    return s;
  };
  buffer.append({sample(0), sample(10), sample(20)});
  buffer.append({sample(20), sample(30)});  // overlapping run: the repeated sample is dropped
  ASSERT_EQ(buffer.samples().size(), 4u);
  const std::vector<sensors::ImuSample> interval = buffer.startInterval(25);
  EXPECT_EQ(interval.size(), 4u);
  ASSERT_EQ(buffer.samples().size(), 2u);  // from the last sample at or before 25
  EXPECT_EQ(buffer.samples().front().t_ns, 20);
}

TEST(ImuSampleBuffer, JoinsTwoKeyFrameIntervalsIntoOneStrictlyIncreasingRun) {
  const auto run = [](std::initializer_list<TimeNs> times) {
    std::vector<sensors::ImuSample> samples;
    for (const TimeNs t : times) {
      sensors::ImuSample s;
      s.t_ns = t;
      samples.push_back(s);
    }
    return samples;
  };
  const auto timesOf = [](const std::vector<sensors::ImuSample>& samples) {
    std::vector<TimeNs> times;
    for (const sensors::ImuSample& s : samples)
      times.push_back(s.t_ns);
    return times;
  };
  // A keyframe at 25 after one at 5: its interval brackets [5, 25], the next one starts at the
  // last sample at or before 25 (ImuSampleBuffer::startInterval).
  EXPECT_EQ(timesOf(joinImuSamples(run({0, 10, 20, 30}), run({20, 30, 40}))),
            (std::vector<TimeNs>{0, 10, 20, 30, 40}));
  EXPECT_EQ(timesOf(joinImuSamples(run({0, 10}), {})), (std::vector<TimeNs>{0, 10}));
  EXPECT_EQ(timesOf(joinImuSamples({}, run({20, 30}))), (std::vector<TimeNs>{20, 30}));
}

TEST(ImuGap, FindsTheLastStretchLongerThanTheLimit) {
  const auto at = [](TimeNs t) {
    sensors::ImuSample s;
    s.t_ns = t;
    return s;
  };
  const std::vector<sensors::ImuSample> samples = {at(0), at(5), at(30), at(35), at(80), at(85)};
  EXPECT_FALSE(findImuGap(samples, 45).has_value());  // the 45 ns stretch is at the limit
  const std::optional<ImuGap> gap = findImuGap(samples, 20);
  ASSERT_TRUE(gap.has_value());
  EXPECT_EQ(*gap, (ImuGap{35, 80}));
  EXPECT_EQ(findImuGap(samples, 44), (ImuGap{35, 80}));
  EXPECT_FALSE(findImuGap({at(0)}, 1).has_value());
}

TEST(ImuSampleBuffer, RestartsAfterAGapSoThatNoPredictionSpansIt) {
  const auto at = [](TimeNs t) {
    sensors::ImuSample s;
    s.t_ns = t;
    return s;
  };
  ImuSampleBuffer buffer;
  buffer.append({at(0), at(10), at(20)});
  buffer.restartAt({at(20), at(500), at(510)}, 500);
  ASSERT_EQ(buffer.samples().size(), 2u);
  EXPECT_EQ(buffer.samples().front().t_ns, 500);
  map::KeyFrame keyframe;  // inserted at 15, before the gap
  keyframe.t_ns = 15;
  EXPECT_FALSE(predictFromKeyFrame(keyframe, buffer.samples(), 505, SE3d(), imu::ImuNoise{}, {})
                   .has_value());
}

TEST(InertialPrediction, PredictsTheTruePoseFromTheKeyFrameState) {
  const sim::Se3Spline motion = test::livelyMotion(2.0);
  sim::ImuNoiseOptions imu_options;
  imu_options.noise = false;
  const sim::ImuSequence imu =
      sim::ImuSimulator(imu_options)
          .simulate(motion, {kMotionStartNs, kMotionStartNs + secondsToNs(1.5)});
  const std::vector<sensors::ImuSample> samples = test::toImuSamples(imu.measurements);

  map::KeyFrame keyframe;
  keyframe.t_ns = kMotionStartNs + secondsToNs(0.5);
  const sim::Se3SplineState state = motion.state(keyframe.t_ns);
  keyframe.T_w_b = state.T_w_b;
  keyframe.v_w = state.v_w;
  keyframe.bg = imu_options.initial_gyroscope_bias;
  keyframe.ba = imu_options.initial_accelerometer_bias;
  const TimeNs t_ns = keyframe.t_ns + secondsToNs(0.4);
  InertialPriorOptions options;
  const auto prediction =
      predictFromKeyFrame(keyframe, samples, t_ns, SE3d(), test::noiseOf(imu_options), options);
  ASSERT_TRUE(prediction);
  const sim::Se3SplineState truth = motion.state(t_ns);
  EXPECT_LT((prediction->T_w_b.t - truth.T_w_b.t).norm(), 5e-4);
  EXPECT_LT(prediction->T_w_b.q.angularDistance(truth.T_w_b.q), 1e-4);
  EXPECT_LT((prediction->v_w - truth.v_w).norm(), 2e-3);
  // Prior: the keyframe's velocity uncertainty over 0.4 s dominates the position std.
  const Eigen::Matrix<double, 6, 6> covariance = prediction->prior.information.inverse();
  const double expected_position_variance =
      options.position_sigma_m * options.position_sigma_m +
      0.4 * 0.4 * options.velocity_sigma * options.velocity_sigma;
  EXPECT_NEAR(covariance(3, 3), expected_position_variance, 0.01 * expected_position_variance);
  // Not bracketed: no prediction.
  EXPECT_FALSE(predictFromKeyFrame(keyframe, samples, kMotionStartNs + secondsToNs(1.6), SE3d(),
                                   test::noiseOf(imu_options), options));
}

/// An IMU turned about all three axes and mounted 32 cm from the body origin.
SE3d rotatedOffsetImu() {
  return SE3d(expSO3(Eigen::Vector3d(0.4, -1.1, 0.7)), Eigen::Vector3d(0.25, -0.15, 0.1));
}

/// A keyframe at t_ns on `motion` with the true state of an IMU at T_b_i: the body pose, the IMU
/// origin's velocity v_b + R_w_b (omega_b x t_b_i) and the simulator's initial biases.
map::KeyFrame keyFrameOn(const sim::Se3Spline& motion, TimeNs t_ns, const SE3d& T_b_i,
                         const sim::ImuNoiseOptions& imu) {
  const sim::Se3SplineState state = motion.state(t_ns);
  map::KeyFrame keyframe;
  keyframe.t_ns = t_ns;
  keyframe.T_w_b = state.T_w_b;
  keyframe.v_w = state.v_w + state.T_w_b.q * state.omega_b.cross(T_b_i.t);
  keyframe.bg = imu.initial_gyroscope_bias;
  keyframe.ba = imu.initial_accelerometer_bias;
  return keyframe;
}

/// Noise-free samples of an IMU at T_b_i on `motion` over its first 1.5 s.
std::vector<sensors::ImuSample> imuSamples(const sim::Se3Spline& motion, const SE3d& T_b_i,
                                           const sim::ImuNoiseOptions& imu) {
  return test::toImuSamples(
      sim::ImuSimulator(imu, T_b_i)
          .simulate(motion, {kMotionStartNs, kMotionStartNs + secondsToNs(1.5)})
          .measurements);
}

TEST(InertialPrediction, PredictsTheTrueBodyPoseWithARotatedOffsetImu) {
  const sim::Se3Spline motion = test::livelyMotion(2.0);
  const SE3d T_b_i = rotatedOffsetImu();
  sim::ImuNoiseOptions imu_options;
  imu_options.noise = false;
  const map::KeyFrame keyframe =
      keyFrameOn(motion, kMotionStartNs + secondsToNs(0.5), T_b_i, imu_options);
  const TimeNs t_ns = keyframe.t_ns + secondsToNs(0.4);
  const auto prediction = predictFromKeyFrame(keyframe, imuSamples(motion, T_b_i, imu_options),
                                              t_ns, T_b_i, test::noiseOf(imu_options), {});
  ASSERT_TRUE(prediction);
  const sim::Se3SplineState truth = motion.state(t_ns);
  EXPECT_LT((prediction->T_w_b.t - truth.T_w_b.t).norm(), 5e-4);
  EXPECT_LT(prediction->T_w_b.q.angularDistance(truth.T_w_b.q), 1e-4);
  const Eigen::Vector3d v_imu = truth.v_w + truth.T_w_b.q * truth.omega_b.cross(T_b_i.t);
  EXPECT_LT((prediction->v_w - v_imu).norm(), 2e-3);
}

TEST(InertialPrediction, PriorCovarianceMatchesMonteCarloWithARotatedOffsetImu) {
  // The prior's covariance must be that of the body pose the preintegration predicts. Draw the
  // errors (dphi, dv, dp) of the preintegrated deltas from their covariance, predict the IMU pose
  // with the perturbed deltas, move it to the body (T_w_b = T_w_i T_i_b) and collect the error in
  // the prior's parameterisation [Log(R_mean^T R) (body frame); p - p_mean (world)].
  const sim::Se3Spline motion = test::livelyMotion(2.0);
  const SE3d T_b_i = rotatedOffsetImu();
  sim::ImuNoiseOptions imu_options;
  imu_options.noise = false;
  const std::vector<sensors::ImuSample> samples = imuSamples(motion, T_b_i, imu_options);
  const map::KeyFrame keyframe =
      keyFrameOn(motion, kMotionStartNs + secondsToNs(0.5), T_b_i, imu_options);
  const TimeNs t_ns = keyframe.t_ns + secondsToNs(0.4);
  // A noisy gyroscope, so that rotation errors (through the lever arm and gravity) weigh in the
  // position; a negligible keyframe uncertainty, so that the prior is the preintegration's alone.
  imu::ImuNoise noise = test::noiseOf(imu_options);
  noise.gyro_noise_density = 5e-3;
  InertialPriorOptions options;
  options.velocity_sigma = 1e-9;
  options.position_sigma_m = 1e-9;
  options.rotation_sigma_deg = 1e-7;
  const auto prediction = predictFromKeyFrame(keyframe, samples, t_ns, T_b_i, noise, options);
  ASSERT_TRUE(prediction);
  const imu::Matrix6d covariance = prediction->prior.information.inverse();

  imu::Preintegration preintegration(imu::Bias{keyframe.bg, keyframe.ba}, noise);
  preintegration.integrateBetween(samples, keyframe.t_ns, t_ns);
  const SE3d T_w_i = keyframe.T_w_b * T_b_i;
  const double dt = preintegration.deltaTime();
  using Vector9d = Eigen::Matrix<double, 9, 1>;
  const auto bodyPoseOf = [&](const Vector9d& e) {
    const Eigen::Matrix3d R_w_i =
        T_w_i.rotation() * preintegration.deltaRotation() * expSO3(e.head<3>());
    const Eigen::Vector3d p_w_i = T_w_i.t + keyframe.v_w * dt +
                                  0.5 * dt * dt * imu::gravityVector() +
                                  T_w_i.rotation() * (preintegration.deltaPosition() + e.tail<3>());
    return SE3d(R_w_i, p_w_i) * T_b_i.inverse();
  };
  const SE3d mean = bodyPoseOf(Vector9d::Zero());
  ASSERT_LT((mean.t - prediction->T_w_b.t).norm(), 1e-12);
  ASSERT_LT(mean.q.angularDistance(prediction->T_w_b.q), 1e-12);

  const Eigen::Matrix<double, 9, 9> L =
      Eigen::LLT<imu::Matrix9d>(preintegration.covariance()).matrixL();
  std::mt19937_64 rng(11);
  std::normal_distribution<double> gauss;
  constexpr int kDraws = 20000;
  imu::Matrix6d sum = imu::Matrix6d::Zero();
  for (int k = 0; k < kDraws; ++k) {
    Vector9d z;
    for (int i = 0; i < 9; ++i)
      z(i) = gauss(rng);
    const SE3d T_w_b = bodyPoseOf(L * z);
    Eigen::Matrix<double, 6, 1> r;
    r << logSO3(mean.rotation().transpose() * T_w_b.rotation()), T_w_b.t - mean.t;
    sum += r * r.transpose();
  }
  const imu::Matrix6d monte_carlo = sum / kDraws;
  // In the prior's own whitening the Monte-Carlo covariance is the identity up to sampling noise
  // (about 0.01 per entry with 20000 draws).
  const imu::Matrix6d S = imu::inverseSquareRoot<6>(covariance);
  const double deviation = (S * monte_carlo * S - imu::Matrix6d::Identity()).cwiseAbs().maxCoeff();
  std::cout << "[ info ] prior vs Monte Carlo: largest entry of S C_mc S - I " << deviation
            << "; position std " << std::sqrt(covariance.bottomRightCorner<3, 3>().trace()) * 1e3
            << " mm (Monte Carlo " << std::sqrt(monte_carlo.bottomRightCorner<3, 3>().trace()) * 1e3
            << " mm)\n";
  EXPECT_LT(deviation, 0.06);
}

TEST(InertialPrediction, RejectsInvalidPriorOptions) {
  InertialPriorOptions options;
  options.velocity_sigma = 0.0;
  EXPECT_THROW(options.validate(), OptionError);
}

}  // namespace
}  // namespace superdyna::tracking

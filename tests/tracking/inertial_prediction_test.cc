#include "superdyna/tracking/inertial_prediction.h"

#include <gtest/gtest.h>

#include "imu/imu_test_motion.h"
#include "superdyna/core/error.h"

namespace superdyna::tracking {
namespace {

using test::kMotionStartNs;

TEST(ImuSampleBuffer, HandsOverTheSamplesBracketingEachKeyFrameInterval) {
  ImuSampleBuffer buffer;
  const auto sample = [](TimeNs t) {
    io::ImuSample s;
    s.t_ns = t;
    s.gyro = Eigen::Vector3d(0.1, 0.0, 0.0);
    s.accel = Eigen::Vector3d(0.0, 0.0, 9.81);
    return s;
  };
  buffer.append({sample(0), sample(10), sample(20)});
  buffer.append({sample(20), sample(30)});  // overlapping run: the repeated sample is dropped
  ASSERT_EQ(buffer.samples().size(), 4u);
  const std::vector<io::ImuSample> interval = buffer.startInterval(25);
  EXPECT_EQ(interval.size(), 4u);
  ASSERT_EQ(buffer.samples().size(), 2u);  // from the last sample at or before 25
  EXPECT_EQ(buffer.samples().front().t_ns, 20);
}

TEST(InertialPrediction, PredictsTheTruePoseFromTheKeyFrameState) {
  const sim::Se3Spline motion = test::livelyMotion(2.0);
  sim::ImuNoiseOptions imu_options;
  imu_options.noise = false;
  const sim::ImuSequence imu =
      sim::ImuSimulator(imu_options)
          .simulate(motion, {kMotionStartNs, kMotionStartNs + secondsToNs(1.5)});
  const std::vector<io::ImuSample> samples = test::toImuSamples(imu.measurements);

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

TEST(InertialPrediction, RejectsInvalidPriorOptions) {
  InertialPriorOptions options;
  options.velocity_sigma = 0.0;
  EXPECT_THROW(options.validate(), OptionError);
}

}  // namespace
}  // namespace superdyna::tracking

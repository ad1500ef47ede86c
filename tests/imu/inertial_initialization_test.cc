#include "superdyna/imu/inertial_initialization.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>

#include "imu/imu_test_motion.h"
#include "superdyna/core/error.h"

namespace superdyna::imu {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
using test::kMotionStartNs;

/// A keyframe chain as vision would give it, with the ground truth to compare against.
struct Scenario {
  InertialInitInput input;
  Eigen::Vector3d gravity_dir_v;  ///< True gravity direction in the visual frame.
  double scale = 1.0;             ///< True metric length of one visual unit.
  std::vector<Eigen::Vector3d> v_v;
  Bias mean_bias;  ///< Simulator biases averaged over the window.
};

/// 10 keyframes 1/3 s apart (3 s) on the lively motion, IMU at 200 Hz. The visual frame v is
/// rotated and shifted against the world and, when `scale` != 1, measured in units of `scale` m.
/// `pose_noise_m` / `pose_noise_rad` perturb the visual poses (0: exact).
Scenario makeScenario(const sim::ImuNoiseOptions& imu_options, double scale,
                      double pose_noise_m = 0.0, double pose_noise_rad = 0.0) {
  const sim::Se3Spline motion = test::livelyMotion(3.6);
  const sim::ImuSequence imu =
      sim::ImuSimulator(imu_options)
          .simulate(motion, {kMotionStartNs, kMotionStartNs + secondsToNs(3.5)});
  const std::vector<sensors::ImuSample> samples = test::toImuSamples(imu.measurements);

  const Eigen::Matrix3d R_v_w = expSO3(Eigen::Vector3d(0.4, -0.7, 1.2));
  const Eigen::Vector3d t_v_w(2.0, -1.0, 0.5);
  std::mt19937 rng(42);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const auto noise3 = [&](double sigma) -> Eigen::Vector3d {
    const double x = gauss(rng), y = gauss(rng), z = gauss(rng);
    return sigma * Eigen::Vector3d(x, y, z);
  };

  Scenario scenario;
  scenario.scale = scale;
  scenario.gravity_dir_v = R_v_w * Eigen::Vector3d(0.0, 0.0, -1.0);
  constexpr int kKeyframes = 10;
  std::vector<TimeNs> times;
  for (int k = 0; k < kKeyframes; ++k) {
    times.push_back(kMotionStartNs + secondsToNs(0.2) + k * secondsToNs(1.0 / 3.0));
  }
  for (int k = 0; k < kKeyframes; ++k) {
    const sim::Se3SplineState s = motion.state(times[k]);
    const Eigen::Matrix3d R_v_b = expSO3(noise3(pose_noise_rad)) * R_v_w * s.T_w_b.rotation();
    const Eigen::Vector3d p_v = (R_v_w * s.T_w_b.t + t_v_w + noise3(pose_noise_m)) / scale;
    scenario.input.T_v_b.emplace_back(R_v_b, p_v);
    scenario.v_v.push_back(R_v_w * s.v_w);
    if (k + 1 < kKeyframes) {
      Preintegration pre(Bias{}, test::noiseOf(imu_options));  // bias unknown: linearise at 0
      pre.integrateBetween(samples, times[k], times[k + 1]);
      scenario.input.preintegrations.push_back(pre);
    }
  }
  int count = 0;
  for (const sim::ImuState& state : imu.states) {
    if (state.t_ns < times.front() || state.t_ns > times.back()) continue;
    scenario.mean_bias.bg += state.bg;
    scenario.mean_bias.ba += state.ba;
    ++count;
  }
  scenario.mean_bias.bg /= count;
  scenario.mean_bias.ba /= count;
  return scenario;
}

struct Errors {
  double gravity_deg;
  double scale_rel;
  double bg;        ///< rad/s
  double ba;        ///< m/s^2
  double velocity;  ///< worst, m/s
};

Errors compare(const InertialInitResult& result, const Scenario& truth) {
  Errors e;
  e.gravity_deg =
      std::acos(std::clamp(result.gravity_dir_v.dot(truth.gravity_dir_v), -1.0, 1.0)) * kRadToDeg;
  e.scale_rel = std::abs(result.scale / truth.scale - 1.0);
  e.bg = (result.bias.bg - truth.mean_bias.bg).norm();
  e.ba = (result.bias.ba - truth.mean_bias.ba).norm();
  e.velocity = 0.0;
  for (std::size_t k = 0; k < truth.v_v.size(); ++k) {
    e.velocity = std::max(e.velocity, (result.v_v[k] - truth.v_v[k]).norm());
  }
  std::cout << "  gravity " << e.gravity_deg << " deg, scale " << result.scale << " (true "
            << truth.scale << ", error " << 100.0 * e.scale_rel << " %), |bg err| " << e.bg
            << " rad/s, |ba err| " << e.ba << " m/s^2, worst velocity " << e.velocity
            << " m/s, cost " << result.initial_cost << " -> " << result.final_cost << " in "
            << result.iterations << " iterations\n";
  return e;
}

TEST(InertialInitTest, ExactImuMonocularRecoversEverything) {
  sim::ImuNoiseOptions imu_options;
  imu_options.noise = false;
  const Scenario scenario = makeScenario(imu_options, 2.5);
  InertialInitOptions options;
  options.initial_scale = 1.0;     // 2.5x off
  options.check_gradients = true;  // Ceres checks the analytic Jacobians at every step
  std::cout << "[ exact IMU, monocular ]\n";
  const InertialInitResult result = initializeInertial(scenario.input, options);
  const Errors e = compare(result, scenario);
  EXPECT_TRUE(result.converged);
  EXPECT_LT(e.gravity_deg, 0.01);
  EXPECT_LT(e.scale_rel, 1e-3);
  EXPECT_LT(e.bg, 1e-4);
  EXPECT_LT(e.ba, 5e-3);
  EXPECT_LT(e.velocity, 5e-3);
  EXPECT_LT(result.final_cost, 1e-3 * result.initial_cost);
  // R_w_v maps the estimated gravity direction to -z.
  EXPECT_LT((result.R_w_v * result.gravity_dir_v - Eigen::Vector3d(0, 0, -1)).norm(), 1e-12);
}

TEST(InertialInitTest, NoisyImuMonocular) {
  const sim::ImuNoiseOptions imu_options;  // EuRoC noise and random walk
  const Scenario scenario = makeScenario(imu_options, 2.5);
  InertialInitOptions options;
  std::cout << "[ noisy IMU (EuRoC ADIS16448 model), monocular ]\n";
  const InertialInitResult result = initializeInertial(scenario.input, options);
  const Errors e = compare(result, scenario);
  EXPECT_TRUE(result.converged);
  EXPECT_LT(e.gravity_deg, 0.5);
  EXPECT_LT(e.scale_rel, 0.01);
  EXPECT_LT(e.bg, 2e-3);
  EXPECT_LT(e.ba, 0.05);
  EXPECT_LT(e.velocity, 0.03);
}

TEST(InertialInitTest, NoisyImuAndNoisyVisionMonocular) {
  const sim::ImuNoiseOptions imu_options;
  // 2 mm and 0.05 deg of pose noise from vision. The poses are held fixed and the residuals are
  // weighted by the IMU noise alone, so the estimate degrades with the visual noise.
  const Scenario scenario = makeScenario(imu_options, 0.4, 0.002, 0.05 / kRadToDeg);
  InertialInitOptions options;
  std::cout << "[ noisy IMU, visual poses with 2 mm / 0.05 deg noise, monocular ]\n";
  const InertialInitResult result = initializeInertial(scenario.input, options);
  const Errors e = compare(result, scenario);
  EXPECT_LT(e.gravity_deg, 1.0);
  EXPECT_LT(e.scale_rel, 0.02);
}

TEST(InertialInitTest, NoisyImuStereoKeepsScale) {
  const sim::ImuNoiseOptions imu_options;
  const Scenario scenario = makeScenario(imu_options, 1.0);
  InertialInitOptions options;
  options.estimate_scale = false;
  std::cout << "[ noisy IMU, stereo (metric, scale fixed) ]\n";
  const InertialInitResult result = initializeInertial(scenario.input, options);
  const Errors e = compare(result, scenario);
  EXPECT_EQ(result.scale, 1.0);
  EXPECT_LT(e.gravity_deg, 0.5);
  EXPECT_LT(e.bg, 2e-3);
  EXPECT_LT(e.ba, 0.05);
}

TEST(InertialInitTest, RejectsBadInputAndOptions) {
  sim::ImuNoiseOptions imu_options;
  imu_options.noise = false;
  Scenario scenario = makeScenario(imu_options, 1.0);
  InertialInitInput short_input = scenario.input;
  short_input.T_v_b.resize(2);
  short_input.preintegrations.resize(1, short_input.preintegrations.front());
  EXPECT_THROW(initializeInertial(short_input), OptionError);
  InertialInitInput mismatched = scenario.input;
  mismatched.preintegrations.pop_back();
  EXPECT_THROW(initializeInertial(mismatched), OptionError);
  InertialInitOptions bad;
  bad.initial_scale = 0.0;
  EXPECT_THROW(initializeInertial(scenario.input, bad), OptionError);
  bad = {};
  bad.reintegration_rounds = -1;
  EXPECT_THROW(bad.validate(), OptionError);
}

TEST(InertialInitTest, GravityAlignedRotationIsMinimal) {
  const Eigen::Vector3d g_v = Eigen::Vector3d(0.1, -0.2, -1.0).normalized();
  const Eigen::Matrix3d R_w_v = gravityAlignedRotation(g_v);
  EXPECT_LT((R_w_v * g_v - Eigen::Vector3d(0, 0, -1)).norm(), 1e-12);
  // The smallest rotation turns about an axis perpendicular to both directions.
  EXPECT_NEAR(logSO3(R_w_v).dot(g_v), 0.0, 1e-12);
  EXPECT_NEAR(rotationAngle(R_w_v), std::acos(-g_v.z()), 1e-12);
}

}  // namespace
}  // namespace superdyna::imu

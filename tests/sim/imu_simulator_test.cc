#include "superdyna/sim/imu_simulator.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <string>

#include "superdyna/core/error.h"
#include "superdyna/io/trajectory_io.h"
#include "superdyna/sim/procedural_trajectory.h"
#include "support/test_support.h"

namespace superdyna::sim {
namespace {

constexpr TimeNs kT0Ns = 1'403'636'580'000'000'000;
constexpr TimeNs kKnotNs = 100'000'000;  // 0.1 s.
constexpr double kRadToDeg = 180.0 / M_PI;

/// A smooth analytic motion (position within metres, a slow spin plus wobble) as a spline.
Se3Spline gentleMotion(double duration_s) {
  const auto poseAt = [](TimeNs t_ns) {
    const double t = nsToSeconds(t_ns - kT0Ns);
    const Eigen::Vector3d p(std::sin(0.3 * t), std::cos(0.2 * t), 1.0 + 0.1 * std::sin(t));
    const Eigen::Vector3d r(0.1 * std::sin(0.5 * t), 0.2 * std::cos(0.3 * t), 0.4 * t);
    return SE3d(expSO3(r), p);
  };
  return Se3Spline::fromFunction(poseAt, {kT0Ns, kT0Ns + secondsToNs(duration_s)}, kKnotNs);
}

/// A drone-like flight: the procedural Lissajous trajectory fitted with 0.1 s knots.
Se3Spline lissajousMotion() {
  LissajousOptions options;
  options.duration_s = 30.0;
  options.rate_hz = 100.0;
  options.period_s = 15.0;
  options.tilt_rad = 0.1;
  return Se3Spline::fit(makeLissajousTrajectory(options), kKnotNs);
}

ImuNoiseOptions noiseFree() {
  ImuNoiseOptions options;
  options.noise = false;
  return options;
}

// ---------------------------------------------------------------------------------------------
// Strapdown integration for the tests: classical RK4 on (R, v, p) with R' = R hat(omega_b),
// v' = R f_b + g_w, p' = v, the IMU signal linearly interpolated between samples (midpoint value =
// average of the two samples); R is projected back onto SO(3) after each step.

struct NavState {
  Eigen::Matrix3d R_w_b;
  Eigen::Vector3d v_w;
  Eigen::Vector3d p_w;
};

struct ImuSignal {
  Eigen::Vector3d omega_b;
  Eigen::Vector3d f_b;  ///< Specific force.
};

NavState derivative(const NavState& x, const ImuSignal& s, const Eigen::Vector3d& g_w) {
  return {x.R_w_b * hat(s.omega_b), x.R_w_b * s.f_b + g_w, x.v_w};
}

NavState advance(const NavState& x, const NavState& dx, double h) {
  return {x.R_w_b + h * dx.R_w_b, x.v_w + h * dx.v_w, x.p_w + h * dx.p_w};
}

NavState rk4Step(const NavState& x, const ImuSignal& s0, const ImuSignal& s1, double h,
                 const Eigen::Vector3d& g_w) {
  const ImuSignal mid{0.5 * (s0.omega_b + s1.omega_b), 0.5 * (s0.f_b + s1.f_b)};
  const NavState k1 = derivative(x, s0, g_w);
  const NavState k2 = derivative(advance(x, k1, 0.5 * h), mid, g_w);
  const NavState k3 = derivative(advance(x, k2, 0.5 * h), mid, g_w);
  const NavState k4 = derivative(advance(x, k3, h), s1, g_w);
  NavState next{x.R_w_b + h / 6.0 * (k1.R_w_b + 2.0 * k2.R_w_b + 2.0 * k3.R_w_b + k4.R_w_b),
                x.v_w + h / 6.0 * (k1.v_w + 2.0 * k2.v_w + 2.0 * k3.v_w + k4.v_w),
                x.p_w + h / 6.0 * (k1.p_w + 2.0 * k2.p_w + 2.0 * k3.p_w + k4.p_w)};
  next.R_w_b = nearestRotation(next.R_w_b);
  return next;
}

/// Bias-corrected signal of sample k (the biases are known ground truth here).
ImuSignal correctedSignal(const ImuSequence& imu, std::size_t k) {
  return {imu.measurements[k].gyro - imu.states[k].bg,
          imu.measurements[k].accel - imu.states[k].ba};
}

/// Integrates from the true state at sample `first` over `steps` samples.
NavState integrate(const ImuSequence& imu, std::size_t first, std::size_t steps, double gravity) {
  const Eigen::Vector3d g_w(0.0, 0.0, -gravity);
  const ImuState& s = imu.states[first];
  NavState x{s.T_w_b.rotation(), s.v_w, s.T_w_b.t};
  for (std::size_t k = first; k < first + steps; ++k) {
    const double h = nsToSeconds(imu.measurements[k + 1].t_ns - imu.measurements[k].t_ns);
    x = rk4Step(x, correctedSignal(imu, k), correctedSignal(imu, k + 1), h, g_w);
  }
  return x;
}

struct IntegrationError {
  double position_m = 0.0;
  double rotation_deg = 0.0;
  double velocity_mps = 0.0;
};

/// Largest error over 1 s windows starting every `stride` samples.
IntegrationError worstOneSecondWindow(const ImuSequence& imu, std::size_t stride) {
  constexpr std::size_t kSteps = 200;  // 1 s at 200 Hz.
  IntegrationError worst;
  for (std::size_t first = 0; first + kSteps < imu.states.size(); first += stride) {
    const NavState x = integrate(imu, first, kSteps, 9.81);
    const ImuState& truth = imu.states[first + kSteps];
    worst.position_m = std::max(worst.position_m, (x.p_w - truth.T_w_b.t).norm());
    worst.velocity_mps = std::max(worst.velocity_mps, (x.v_w - truth.v_w).norm());
    worst.rotation_deg =
        std::max(worst.rotation_deg,
                 kRadToDeg * rotationAngle(x.R_w_b.transpose() * truth.T_w_b.rotation()));
  }
  return worst;
}

// ---------------------------------------------------------------------------------------------

TEST(ImuSimulatorTest, SamplesEveryFiveMillisecondsAt200Hz) {
  const Se3Spline motion = gentleMotion(10.0);
  const ImuSequence imu = ImuSimulator(noiseFree()).simulate(motion);
  ASSERT_EQ(imu.measurements.size(), 2001u);
  ASSERT_EQ(imu.states.size(), imu.measurements.size());
  EXPECT_EQ(imu.measurements.front().t_ns, motion.validRange().begin);
  for (std::size_t k = 1; k < imu.measurements.size(); ++k) {
    ASSERT_EQ(imu.measurements[k].t_ns - imu.measurements[k - 1].t_ns, 5'000'000) << k;
    ASSERT_EQ(imu.states[k].t_ns, imu.measurements[k].t_ns);
  }
  const ImuSequence part =
      ImuSimulator(noiseFree())
          .simulate(motion, {kT0Ns + kNsPerSecond + 1, kT0Ns + 2 * kNsPerSecond});
  EXPECT_EQ(part.measurements.size(), 200u);  // The sample at 2 s + 1 ns is past the end.
}

TEST(ImuSimulatorTest, WithoutNoiseMeasuresTheExactMotionPlusConstantBiases) {
  const Se3Spline motion = gentleMotion(5.0);
  const ImuNoiseOptions options = noiseFree();
  const ImuSequence imu = ImuSimulator(options).simulate(motion);
  const Eigen::Vector3d g_w(0.0, 0.0, -9.81);
  for (std::size_t k = 0; k < imu.measurements.size(); k += 7) {
    const Se3SplineState s = motion.state(imu.measurements[k].t_ns);
    const Eigen::Vector3d f_b = s.T_w_b.rotation().transpose() * (s.a_w - g_w);
    EXPECT_LT((imu.measurements[k].gyro - s.omega_b - options.initial_gyroscope_bias).norm(),
              1e-12);
    EXPECT_LT((imu.measurements[k].accel - f_b - options.initial_accelerometer_bias).norm(), 1e-12);
    EXPECT_EQ(imu.states[k].bg, options.initial_gyroscope_bias);
    EXPECT_EQ(imu.states[k].ba, options.initial_accelerometer_bias);
    EXPECT_LT((imu.states[k].v_w - s.v_w).norm(), 1e-15);
  }
}

TEST(ImuSimulatorTest, AtRestTheAccelerometerMeasuresGravityUpwards) {
  const std::vector<SE3d> still(6);  // Identity poses.
  const Se3Spline motion(kT0Ns, kKnotNs, still);
  ImuNoiseOptions options = noiseFree();
  options.initial_gyroscope_bias.setZero();
  options.initial_accelerometer_bias.setZero();
  const ImuSequence imu = ImuSimulator(options).simulate(motion);
  ASSERT_FALSE(imu.measurements.empty());
  for (const ImuMeasurement& m : imu.measurements) {
    EXPECT_LT(m.gyro.norm(), 1e-15);
    EXPECT_LT((m.accel - Eigen::Vector3d(0.0, 0.0, 9.81)).norm(), 1e-12);
  }
}

/// Prints the worst 1 s integration error of `imu` against its states (`what` names the motion)
/// and expects it within 1 mm and 0.01 deg.
void expectIntegratesBack(const ImuSequence& imu, const std::string& what) {
  const IntegrationError e = worstOneSecondWindow(imu, 50);
  std::cout << fmt::format(
      "[ info ] {}, worst 1 s window: position {:.4f} mm, rotation {:.5f} deg, velocity {:.4f} "
      "mm/s\n",
      what, 1e3 * e.position_m, e.rotation_deg, 1e3 * e.velocity_mps);
  EXPECT_LT(e.position_m, 1e-3) << what;
  EXPECT_LT(e.rotation_deg, 0.01) << what;
}

TEST(ImuSimulatorTest, NoiseFreeMeasurementsIntegrateBackToTheProceduralTrajectory) {
  expectIntegratesBack(ImuSimulator(noiseFree()).simulate(lissajousMotion()), "Lissajous");
}

TEST(ImuSimulatorTest, NoiseFreeMeasurementsIntegrateBackToEurocGroundTruth) {
  SUPERDYNA_REQUIRE_SHARED(file, "data/trajectories/euroc/MH_01_easy.txt");
  const Trajectory all = io::readTrajectory(file);
  ASSERT_FALSE(all.empty());
  const TimeNs begin = all.front().t_ns + 40 * kNsPerSecond;
  Trajectory samples;
  for (const StampedPose& p : all) {
    if (p.t_ns >= begin && p.t_ns <= begin + 30 * kNsPerSecond) samples.push_back(p);
  }
  expectIntegratesBack(ImuSimulator(noiseFree()).simulate(Se3Spline::fit(samples, kKnotNs)),
                       "EuRoC MH_01 spline");
}

/// The ground truth moved from the body to an IMU at T_b_i: its pose T_w_b T_b_i and its origin's
/// velocity v_b + R_w_b (omega_b x t_b_i), for worstOneSecondWindow.
ImuSequence atImu(ImuSequence imu, const Se3Spline& motion, const SE3d& T_b_i) {
  for (ImuState& state : imu.states) {
    const Se3SplineState s = motion.state(state.t_ns);
    state.T_w_b = s.T_w_b * T_b_i;
    state.v_w = s.v_w + s.T_w_b.q * s.omega_b.cross(T_b_i.t);
  }
  return imu;
}

TEST(ImuSimulatorTest, OffsetImuMeasurementsIntegrateBackToTheImuTrajectory) {
  // An IMU 37 cm from the body origin, turned about all axes: its gyroscope sees the body rates in
  // its own frame, its accelerometer the acceleration of its own origin, which adds the lever
  // arm's tangential and centripetal terms to the body's.
  const SE3d T_b_i(expSO3(Eigen::Vector3d(0.3, -0.9, 1.4)), Eigen::Vector3d(0.3, -0.2, 0.1));
  const Se3Spline motion = lissajousMotion();
  const ImuSequence imu = ImuSimulator(noiseFree(), T_b_i).simulate(motion);
  for (std::size_t k = 0; k < imu.measurements.size(); k += 101) {
    const Se3SplineState s = motion.state(imu.measurements[k].t_ns);
    EXPECT_LT((T_b_i.q * (imu.measurements[k].gyro - imu.states[k].bg) - s.omega_b).norm(), 1e-12);
    EXPECT_EQ(imu.states[k].T_w_b.t, s.T_w_b.t);  // the ground truth stays the body's
  }
  expectIntegratesBack(atImu(imu, motion, T_b_i), "Lissajous, offset IMU");
  // Without the lever arm's terms (the IMU only turned) the same integration misses by far more.
  const SE3d turned(T_b_i.q, Eigen::Vector3d::Zero());
  const ImuSequence no_lever = ImuSimulator(noiseFree(), turned).simulate(motion);
  const double no_lever_m = worstOneSecondWindow(atImu(no_lever, motion, T_b_i), 50).position_m;
  std::cout << fmt::format("[ info ] without the lever-arm terms: position {:.1f} mm\n",
                           1e3 * no_lever_m);
  EXPECT_GT(no_lever_m, 10.0 * 1e-3);
}

/// Sample standard deviation of the entries of a 3 x n matrix (all axes pooled) and per axis.
struct Spread {
  double pooled = 0.0;
  Eigen::Vector3d per_axis = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
};

Spread spreadOf(const Eigen::Matrix3Xd& values) {
  Spread s;
  const auto n = static_cast<double>(values.cols());
  s.mean = values.rowwise().mean();
  const Eigen::Matrix3Xd centred = values.colwise() - s.mean;
  s.per_axis = (centred.rowwise().squaredNorm() / (n - 1.0)).cwiseSqrt();
  s.pooled = std::sqrt(centred.squaredNorm() / (3.0 * n - 3.0));
  return s;
}

void expectSpread(const Spread& s, double sigma, std::size_t count, const char* what) {
  EXPECT_NEAR(s.pooled / sigma, 1.0, 0.02) << what;
  for (int axis = 0; axis < 3; ++axis) {
    EXPECT_NEAR(s.per_axis[axis] / sigma, 1.0, 0.03) << what << " axis " << axis;
    EXPECT_LT(std::abs(s.mean[axis]), 5.0 * sigma / std::sqrt(static_cast<double>(count)))
        << what << " axis " << axis;
  }
}

TEST(ImuSimulatorTest, NoiseAndBiasWalkHaveTheConfiguredStatistics) {
  const Se3Spline motion = gentleMotion(500.0);  // 100,001 samples at 200 Hz.
  const ImuNoiseOptions options;                 // EuRoC noise, seed 1.
  const ImuSequence imu = ImuSimulator(options).simulate(motion);
  const std::size_t n = imu.measurements.size();
  ASSERT_EQ(n, 100'001u);
  const Eigen::Vector3d g_w(0.0, 0.0, -options.gravity);
  Eigen::Matrix3Xd gyro_noise(3, n), accel_noise(3, n), bg_steps(3, n - 1), ba_steps(3, n - 1);
  for (std::size_t k = 0; k < n; ++k) {
    const auto col = static_cast<Eigen::Index>(k);
    const Se3SplineState s = motion.state(imu.measurements[k].t_ns);
    const Eigen::Vector3d f_b = s.T_w_b.rotation().transpose() * (s.a_w - g_w);
    gyro_noise.col(col) = imu.measurements[k].gyro - s.omega_b - imu.states[k].bg;
    accel_noise.col(col) = imu.measurements[k].accel - f_b - imu.states[k].ba;
    if (k + 1 < n) {
      bg_steps.col(col) = imu.states[k + 1].bg - imu.states[k].bg;
      ba_steps.col(col) = imu.states[k + 1].ba - imu.states[k].ba;
    }
  }
  const Spread gyro = spreadOf(gyro_noise), accel = spreadOf(accel_noise);
  const Spread bg = spreadOf(bg_steps), ba = spreadOf(ba_steps);
  std::cout << fmt::format(
      "[ info ] std / configured: gyro {:.4f}, accel {:.4f}, gyro bias step {:.4f}, accel bias "
      "step {:.4f}\n",
      gyro.pooled / options.gyroscopeNoiseStd(), accel.pooled / options.accelerometerNoiseStd(),
      bg.pooled / options.gyroscopeBiasStepStd(), ba.pooled / options.accelerometerBiasStepStd());
  EXPECT_NEAR(options.gyroscopeNoiseStd(), 1.6968e-4 * std::sqrt(200.0), 1e-15);
  EXPECT_NEAR(options.accelerometerBiasStepStd(), 3.0e-3 * std::sqrt(0.005), 1e-15);
  expectSpread(gyro, options.gyroscopeNoiseStd(), n, "gyro noise");
  expectSpread(accel, options.accelerometerNoiseStd(), n, "accel noise");
  expectSpread(bg, options.gyroscopeBiasStepStd(), n - 1, "gyro bias step");
  expectSpread(ba, options.accelerometerBiasStepStd(), n - 1, "accel bias step");
  EXPECT_EQ(imu.states.front().bg, options.initial_gyroscope_bias);
  EXPECT_EQ(imu.states.front().ba, options.initial_accelerometer_bias);
}

TEST(ImuSimulatorTest, IsDeterministicForASeed) {
  const Se3Spline motion = gentleMotion(5.0);
  ImuNoiseOptions options;
  options.seed = 42;
  const ImuSimulator simulator(options);
  const ImuSequence a = simulator.simulate(motion);
  const ImuSequence b = ImuSimulator(options).simulate(motion);
  ASSERT_EQ(a.measurements.size(), b.measurements.size());
  for (std::size_t k = 0; k < a.measurements.size(); ++k) {
    ASSERT_EQ(a.measurements[k].gyro, b.measurements[k].gyro) << k;
    ASSERT_EQ(a.measurements[k].accel, b.measurements[k].accel) << k;
    ASSERT_EQ(a.states[k].bg, b.states[k].bg) << k;
    ASSERT_EQ(a.states[k].ba, b.states[k].ba) << k;
  }
  EXPECT_EQ(simulator.simulate(motion).measurements.back().accel, a.measurements.back().accel);
  options.seed = 43;
  const ImuSequence c = ImuSimulator(options).simulate(motion);
  EXPECT_NE(a.measurements.back().gyro, c.measurements.back().gyro);
}

TEST(ImuSimulatorTest, RejectsInvalidOptionsAndRanges) {
  const auto expectRejected = [](const auto& change) {
    ImuNoiseOptions options;
    change(options);
    EXPECT_THROW(options.validate(), OptionError);
    EXPECT_THROW(ImuSimulator{options}, OptionError);
  };
  expectRejected([](ImuNoiseOptions& o) { o.rate_hz = 0.0; });
  expectRejected([](ImuNoiseOptions& o) { o.rate_hz = std::nan(""); });
  expectRejected([](ImuNoiseOptions& o) { o.gyroscope_noise_density = -1e-4; });
  expectRejected([](ImuNoiseOptions& o) { o.gyroscope_random_walk = -1.0; });
  expectRejected([](ImuNoiseOptions& o) { o.accelerometer_noise_density = INFINITY; });
  expectRejected([](ImuNoiseOptions& o) { o.accelerometer_random_walk = -3e-3; });
  expectRejected([](ImuNoiseOptions& o) { o.initial_gyroscope_bias.x() = std::nan(""); });
  expectRejected([](ImuNoiseOptions& o) { o.gravity = -9.81; });
  EXPECT_NO_THROW(ImuNoiseOptions{}.validate());

  const Se3Spline motion = gentleMotion(2.0);
  const ImuSimulator simulator(noiseFree());
  const TimeRange valid = motion.validRange();
  EXPECT_THROW(simulator.simulate(motion, {valid.begin - 1, valid.end}), OptionError);
  EXPECT_THROW(simulator.simulate(motion, {valid.begin, valid.end + 1}), OptionError);
  EXPECT_THROW(simulator.simulate(motion, {valid.end, valid.begin}), OptionError);
  EXPECT_EQ(simulator.simulate(motion, {valid.end, valid.end}).measurements.size(), 1u);
}

}  // namespace
}  // namespace superdyna::sim

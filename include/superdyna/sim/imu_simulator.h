#pragma once
// Synthetic IMU measurements from a smooth body motion (an Se3Spline), with the continuous-time
// noise model of Kalibr / OpenVINS: white noise plus random-walk biases on gyroscope and
// accelerometer. World frame z-up, gravity g_w = (0, 0, -gravity). The IMU i is mounted at T_b_i in
// the body frame b of the spline (identity by default: the IMU is the body frame, as in EuRoC);
// its measurements are in its own frame, the ground truth states are those of the body.

#include <cstdint>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"
#include "superdyna/sim/se3_spline.h"

namespace superdyna::sim {

/// Rate and noise of the simulated IMU. Defaults: the ADIS16448 of the EuRoC MAV dataset.
struct ImuNoiseOptions {
  double rate_hz = 200.0;  ///< Sampling rate [Hz], > 0; t_k = start + round(k * 1e9 / rate_hz).
  double gyroscope_noise_density = 1.6968e-4;   ///< White noise [rad/s/sqrt(Hz)], >= 0.
  double gyroscope_random_walk = 1.9393e-5;     ///< Bias random walk [rad/s^2/sqrt(Hz)], >= 0.
  double accelerometer_noise_density = 2.0e-3;  ///< White noise [m/s^2/sqrt(Hz)], >= 0.
  double accelerometer_random_walk = 3.0e-3;    ///< Bias random walk [m/s^3/sqrt(Hz)], >= 0.
  /// When false, measurements are exact (plus the constant initial biases) and no random numbers
  /// are drawn.
  bool noise = true;
  /// Gyroscope bias at the first sample [rad/s] (set to zero for an unbiased IMU).
  Eigen::Vector3d initial_gyroscope_bias = Eigen::Vector3d(-0.002, 0.021, 0.077);
  /// Accelerometer bias at the first sample [m/s^2].
  Eigen::Vector3d initial_accelerometer_bias = Eigen::Vector3d(-0.018, 0.066, 0.031);
  double gravity = 9.81;   ///< Magnitude of gravity [m/s^2], >= 0, along -z of the world.
  std::uint64_t seed = 1;  ///< Seed of the random number generator (std::mt19937_64).

  /// Throws OptionError naming the first invalid field.
  void validate() const;

  /// Discrete white-noise std of one gyroscope sample [rad/s]: density * sqrt(rate).
  double gyroscopeNoiseStd() const;
  /// Discrete white-noise std of one accelerometer sample [m/s^2]: density * sqrt(rate).
  double accelerometerNoiseStd() const;
  /// Std of the gyroscope bias change over one sample period [rad/s]: walk * sqrt(1 / rate).
  double gyroscopeBiasStepStd() const;
  /// Std of the accelerometer bias change over one sample period [m/s^2]: walk * sqrt(1 / rate).
  double accelerometerBiasStepStd() const;
};

/// One IMU sample in the IMU frame.
struct ImuMeasurement {
  TimeNs t_ns = 0;
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();   ///< Angular rate [rad/s].
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();  ///< Specific force [m/s^2].
};

/// Ground truth at a measurement time: the body's motion, the IMU's biases.
struct ImuState {
  TimeNs t_ns = 0;
  SE3d T_w_b;                                     ///< Pose of the body in the world.
  Eigen::Vector3d v_w = Eigen::Vector3d::Zero();  ///< Body origin velocity, world frame [m/s].
  Eigen::Vector3d bg = Eigen::Vector3d::Zero();   ///< Gyroscope bias (IMU frame) [rad/s].
  Eigen::Vector3d ba = Eigen::Vector3d::Zero();   ///< Accelerometer bias (IMU frame) [m/s^2].
};

/// Measurements and the ground-truth states at the same times (same length, same order).
struct ImuSequence {
  std::vector<ImuMeasurement> measurements;
  std::vector<ImuState> states;
};

/// Samples an IMU mounted at T_b_i = (R_b_i, t_b_i) on a body moving along a spline:
///   gyro_k  = R_b_i^T omega_b(t_k) + bg_k + n_g,            n_g ~ N(0, gyroscopeNoiseStd()^2 I)
///   accel_k = R_w_i(t_k)^T (a_w_i(t_k) - g_w) + ba_k + n_a, n_a ~ N(0, accelerometerNoiseStd()^2
///   I) bg_{k+1} = bg_k + w_g, ba_{k+1} = ba_k + w_a,           w ~ N(0, *BiasStepStd()^2 I)
/// with R_w_i = R_w_b R_b_i, the IMU origin's acceleration (lever arm t_b_i, body-frame angular
/// velocity omega_b and acceleration alpha_b of the spline)
///   a_w_i = a_w + R_w_b (alpha_b x t_b_i + omega_b x (omega_b x t_b_i)),
/// and bg_0, ba_0 the initial biases. Deterministic for a seed: every call of simulate() starts
/// a fresh generator from options.seed.
class ImuSimulator {
 public:
  /// Throws OptionError when the options are invalid. T_b_i: pose of the IMU in the body frame.
  explicit ImuSimulator(const ImuNoiseOptions& options, const SE3d& T_b_i = SE3d());

  const ImuNoiseOptions& options() const { return options_; }
  const SE3d& T_b_i() const { return T_b_i_; }

  /// Samples at t_k = range.begin + round(k * 1e9 / rate_hz) for every t_k <= range.end.
  /// Throws OptionError when `range` is not inside motion.validRange() or end < begin.
  ImuSequence simulate(const Se3Spline& motion, TimeRange range) const;
  /// Same over the whole valid range of the spline.
  ImuSequence simulate(const Se3Spline& motion) const;

 private:
  ImuNoiseOptions options_;
  SE3d T_b_i_;
};

}  // namespace superdyna::sim

#pragma once
// Synthetic motion and IMU data shared by the IMU and IMU-factor tests: an analytic, lively body
// motion turned into an Se3Spline (the ground truth) and the simulator's output as io samples.

#include <cmath>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/imu/preintegration.h"
#include "superdyna/io/euroc_dataset.h"
#include "superdyna/sim/imu_simulator.h"
#include "superdyna/sim/se3_spline.h"

namespace superdyna::test {

inline constexpr TimeNs kMotionStartNs = 1'000'000'000'000;  // 1000 s
inline constexpr TimeNs kMotionKnotNs = 50'000'000;          // 0.05 s

/// A hand-held-like motion: about 1 m of translation with 1-2 m/s^2 of acceleration and rotation
/// rates up to about 1 rad/s about all three axes, for `duration_s` seconds from kMotionStartNs.
inline sim::Se3Spline livelyMotion(double duration_s) {
  const auto pose_at = [](TimeNs t_ns) -> SE3d {
    const double t = nsToSeconds(t_ns - kMotionStartNs);
    const Eigen::Vector3d p_w(std::sin(1.3 * t), 0.8 * std::sin(1.7 * t + 0.5),
                              1.5 + 0.3 * std::sin(2.1 * t));
    const Eigen::Vector3d r(0.3 * std::sin(1.1 * t), 0.25 * std::sin(0.9 * t + 1.0),
                            0.6 * std::sin(0.7 * t) + 0.2 * t);
    return SE3d(expSO3(r), p_w);
  };
  return sim::Se3Spline::fromFunction(
      pose_at, {kMotionStartNs, kMotionStartNs + secondsToNs(duration_s)}, kMotionKnotNs);
}

/// The simulator's measurements as io samples.
inline std::vector<sensors::ImuSample> toImuSamples(const std::vector<sim::ImuMeasurement>& in) {
  std::vector<sensors::ImuSample> out;
  out.reserve(in.size());
  for (const sim::ImuMeasurement& m : in)
    out.push_back({m.t_ns, m.gyro, m.accel});
  return out;
}

/// The spline's state at t_ns.
inline imu::NavState navStateAt(const sim::Se3Spline& motion, TimeNs t_ns) {
  const sim::Se3SplineState s = motion.state(t_ns);
  return {s.T_w_b.rotation(), s.T_w_b.t, s.v_w};
}

/// The preintegration noise matching simulator options.
inline imu::ImuNoise noiseOf(const sim::ImuNoiseOptions& options) {
  imu::ImuNoise noise;
  noise.gyro_noise_density = options.gyroscope_noise_density;
  noise.accel_noise_density = options.accelerometer_noise_density;
  noise.gyro_random_walk = options.gyroscope_random_walk;
  noise.accel_random_walk = options.accelerometer_random_walk;
  return noise;
}

}  // namespace superdyna::test

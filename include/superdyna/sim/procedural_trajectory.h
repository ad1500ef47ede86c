#pragma once
// Smooth procedural motion and a model of an estimator's error, for demos and tests that need a
// trajectory with a known answer and no data files.

#include <cstdint>

#include "superdyna/core/trajectory.h"

namespace superdyna::sim {

/// A closed Lissajous-like flight over a room: x = ax sin(w t), y = ay sin(2 w t + phase),
/// z = height + az sin(3 w t); the body's x axis faces the direction of travel (yaw), with small
/// roll and pitch oscillations as on a hovering drone.
struct LissajousOptions {
  double duration_s = 60.0;                     ///< Length of the trajectory [s], > 0.
  double rate_hz = 20.0;                        ///< Pose rate [Hz], > 0.
  double ax_m = 3.0;                            ///< Half-extent along x [m].
  double ay_m = 2.0;                            ///< Half-extent along y [m].
  double az_m = 0.3;                            ///< Vertical oscillation amplitude [m].
  double height_m = 1.2;                        ///< Mean height [m].
  double period_s = 30.0;                       ///< Period of the x oscillation [s], > 0.
  double tilt_rad = 0.05;                       ///< Amplitude of roll/pitch oscillation [rad].
  TimeNs start_ns = 1'000'000'000'000'000'000;  ///< First timestamp [ns].

  /// Throws OptionError naming the first invalid field.
  void validate() const;
};

Trajectory makeLissajousTrajectory(const LissajousOptions& options);

/// How an imperfect estimator deviates from the truth: a slow random-walk drift in position and
/// yaw, white noise on every pose, a scale error, and an unknown world frame.
struct EstimateErrorOptions {
  double position_noise_m = 0.01;           ///< White noise std per axis [m].
  double rotation_noise_rad = 0.002;        ///< White noise std per axis [rad].
  double drift_m_per_sqrt_s = 0.01;         ///< Position random walk [m / sqrt(s)].
  double yaw_drift_rad_per_sqrt_s = 0.001;  ///< Yaw random walk [rad / sqrt(s)].
  double scale = 1.0;                       ///< Scale of the estimate relative to the truth.
  Sim3d world_offset;                       ///< Estimate world frame relative to the true one.
  std::uint64_t seed = 1;                   ///< Seed of the random number generator.

  void validate() const;
};

/// Returns `truth` as an estimator with `options`' errors would report it (same timestamps).
/// Deterministic for a given seed.
Trajectory simulateEstimate(const Trajectory& truth, const EstimateErrorOptions& options);

}  // namespace superdyna::sim

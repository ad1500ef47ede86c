#include "superdyna/sim/procedural_trajectory.h"

#include <cmath>
#include <random>

#include "superdyna/core/error.h"

namespace superdyna::sim {

namespace {

void requirePositive(double value, const char* name) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw OptionError(name, "must be a positive finite number");
  }
}

Eigen::Vector3d lissajousPosition(const LissajousOptions& o, double t) {
  const double w = 2.0 * M_PI / o.period_s;
  return {o.ax_m * std::sin(w * t), o.ay_m * std::sin(2.0 * w * t + 0.5),
          o.height_m + o.az_m * std::sin(3.0 * w * t)};
}

Eigen::Matrix3d lissajousAttitude(const LissajousOptions& o, double t) {
  // Heading from the velocity (central difference of the closed-form position).
  constexpr double kDt = 1e-3;
  const Eigen::Vector3d v = lissajousPosition(o, t + kDt) - lissajousPosition(o, t - kDt);
  const double yaw = std::atan2(v.y(), v.x());
  const double roll = o.tilt_rad * std::sin(2.0 * M_PI * t / 7.0);
  const double pitch = o.tilt_rad * std::cos(2.0 * M_PI * t / 5.0);
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

}  // namespace

void LissajousOptions::validate() const {
  requirePositive(duration_s, "duration_s");
  requirePositive(rate_hz, "rate_hz");
  requirePositive(period_s, "period_s");
  if (ax_m < 0.0 || ay_m < 0.0 || az_m < 0.0 || !std::isfinite(height_m) || tilt_rad < 0.0) {
    throw OptionError("lissajous", "extents and tilt must be non-negative and finite");
  }
}

Trajectory makeLissajousTrajectory(const LissajousOptions& options) {
  options.validate();
  const auto count = static_cast<std::size_t>(std::floor(options.duration_s * options.rate_hz)) + 1;
  const double period_s = 1.0 / options.rate_hz;
  Trajectory trajectory;
  trajectory.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const double t = static_cast<double>(i) * period_s;
    trajectory.push_back({options.start_ns + secondsToNs(t),
                          SE3d(lissajousAttitude(options, t), lissajousPosition(options, t))});
  }
  return trajectory;
}

void EstimateErrorOptions::validate() const {
  if (position_noise_m < 0.0 || rotation_noise_rad < 0.0 || drift_m_per_sqrt_s < 0.0 ||
      yaw_drift_rad_per_sqrt_s < 0.0) {
    throw OptionError("estimate_error", "noise and drift densities must be non-negative");
  }
  requirePositive(scale, "scale");
  requirePositive(world_offset.s, "world_offset.s");
}

Trajectory simulateEstimate(const Trajectory& truth, const EstimateErrorOptions& options) {
  options.validate();
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const auto gaussVector = [&](double sigma) -> Eigen::Vector3d {
    const double x = gauss(rng), y = gauss(rng), z = gauss(rng);
    return Eigen::Vector3d(x, y, z) * sigma;
  };

  Eigen::Vector3d drift = Eigen::Vector3d::Zero();
  double yaw_drift = 0.0;
  Trajectory estimate;
  estimate.reserve(truth.size());
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (i > 0) {
      const double sqrt_dt = std::sqrt(nsToSeconds(truth[i].t_ns - truth[i - 1].t_ns));
      drift += gaussVector(options.drift_m_per_sqrt_s * sqrt_dt);
      yaw_drift += gauss(rng) * options.yaw_drift_rad_per_sqrt_s * sqrt_dt;
    }
    const SE3d& T = truth[i].T_w_x;
    const Eigen::Matrix3d R_drift = expSO3(Eigen::Vector3d(0.0, 0.0, yaw_drift));
    const Eigen::Vector3d p = R_drift * T.t + drift + gaussVector(options.position_noise_m);
    const Eigen::Matrix3d R =
        R_drift * T.rotation() * expSO3(gaussVector(options.rotation_noise_rad));
    const SE3d in_true_frame(R, options.scale * p);
    estimate.push_back({truth[i].t_ns, options.world_offset * in_true_frame});
  }
  return estimate;
}

}  // namespace superdyna::sim

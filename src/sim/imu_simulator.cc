#include "superdyna/sim/imu_simulator.h"

#include <fmt/format.h>

#include <cmath>
#include <random>

#include "superdyna/core/error.h"

namespace superdyna::sim {

namespace {

void requireNonNegative(double value, const char* name) {
  if (!(value >= 0.0) || !std::isfinite(value)) {
    throw OptionError(name, "must be a non-negative finite number");
  }
}

void requireFinite(const Eigen::Vector3d& value, const char* name) {
  if (!value.allFinite()) throw OptionError(name, "must be finite");
}

/// Time of sample k: exact integer nanoseconds when 1e9 / rate_hz is a whole number.
TimeNs sampleTime(TimeNs start_ns, std::int64_t k, double rate_hz) {
  return start_ns + std::llround(static_cast<double>(k) * 1e9 / rate_hz);
}

/// Draws 3 independent N(0, sigma^2) numbers (x, y, z order, so the sequence is reproducible).
class GaussianSource {
 public:
  explicit GaussianSource(std::uint64_t seed) : rng_(seed) {}
  Eigen::Vector3d draw(double sigma) {
    const double x = gauss_(rng_);
    const double y = gauss_(rng_);
    const double z = gauss_(rng_);
    return sigma * Eigen::Vector3d(x, y, z);
  }

 private:
  std::mt19937_64 rng_;
  std::normal_distribution<double> gauss_{0.0, 1.0};
};

/// The exact (noise- and bias-free) measurement at one time of an IMU mounted at T_b_i on the
/// body: the body's rates in the IMU frame; the specific force at the IMU origin, whose
/// acceleration adds the tangential (alpha x t) and centripetal (omega x (omega x t)) terms of
/// the lever arm t = t_b_i to the body's.
ImuMeasurement idealMeasurement(const Se3SplineState& s, const Eigen::Vector3d& g_w,
                                const SE3d& T_b_i) {
  const Eigen::Vector3d& t = T_b_i.t;
  const Eigen::Vector3d lever_b = s.alpha_b.cross(t) + s.omega_b.cross(s.omega_b.cross(t));
  const Eigen::Vector3d a_w_i = s.a_w + s.T_w_b.q * lever_b;
  const Eigen::Quaterniond q_i_b = T_b_i.q.conjugate();
  ImuMeasurement m;
  m.t_ns = s.t_ns;
  m.gyro = q_i_b * s.omega_b;
  m.accel = q_i_b * (s.T_w_b.q.conjugate() * (a_w_i - g_w));
  return m;
}

}  // namespace

void ImuNoiseOptions::validate() const {
  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz) || rate_hz > 1e9) {
    throw OptionError("rate_hz", "must be a positive finite number of at most 1e9");
  }
  requireNonNegative(gyroscope_noise_density, "gyroscope_noise_density");
  requireNonNegative(gyroscope_random_walk, "gyroscope_random_walk");
  requireNonNegative(accelerometer_noise_density, "accelerometer_noise_density");
  requireNonNegative(accelerometer_random_walk, "accelerometer_random_walk");
  requireFinite(initial_gyroscope_bias, "initial_gyroscope_bias");
  requireFinite(initial_accelerometer_bias, "initial_accelerometer_bias");
  requireNonNegative(gravity, "gravity");
}

double ImuNoiseOptions::gyroscopeNoiseStd() const {
  return gyroscope_noise_density * std::sqrt(rate_hz);
}

double ImuNoiseOptions::accelerometerNoiseStd() const {
  return accelerometer_noise_density * std::sqrt(rate_hz);
}

double ImuNoiseOptions::gyroscopeBiasStepStd() const {
  return gyroscope_random_walk / std::sqrt(rate_hz);
}

double ImuNoiseOptions::accelerometerBiasStepStd() const {
  return accelerometer_random_walk / std::sqrt(rate_hz);
}

ImuSimulator::ImuSimulator(const ImuNoiseOptions& options, const SE3d& T_b_i)
    : options_(options), T_b_i_(T_b_i) {
  options_.validate();
}

ImuSequence ImuSimulator::simulate(const Se3Spline& motion) const {
  return simulate(motion, motion.validRange());
}

ImuSequence ImuSimulator::simulate(const Se3Spline& motion, TimeRange range) const {
  const TimeRange valid = motion.validRange();
  if (range.end < range.begin || !valid.contains(range.begin) || !valid.contains(range.end)) {
    throw OptionError("range",
                      fmt::format("[{}, {}] s is not inside the spline's range [{}, {}] s",
                                  formatNsAsSeconds(range.begin), formatNsAsSeconds(range.end),
                                  formatNsAsSeconds(valid.begin), formatNsAsSeconds(valid.end)));
  }
  const Eigen::Vector3d g_w(0.0, 0.0, -options_.gravity);
  GaussianSource noise(options_.seed);
  Eigen::Vector3d bg = options_.initial_gyroscope_bias;
  Eigen::Vector3d ba = options_.initial_accelerometer_bias;
  ImuSequence out;
  for (std::int64_t k = 0;; ++k) {
    const TimeNs t_ns = sampleTime(range.begin, k, options_.rate_hz);
    if (t_ns > range.end) break;
    const Se3SplineState s = motion.state(t_ns);
    ImuMeasurement m = idealMeasurement(s, g_w, T_b_i_);
    m.gyro += bg;
    m.accel += ba;
    out.states.push_back({t_ns, s.T_w_b, s.v_w, bg, ba});
    if (options_.noise) {
      m.gyro += noise.draw(options_.gyroscopeNoiseStd());
      m.accel += noise.draw(options_.accelerometerNoiseStd());
      bg += noise.draw(options_.gyroscopeBiasStepStd());
      ba += noise.draw(options_.accelerometerBiasStepStd());
    }
    out.measurements.push_back(m);
  }
  return out;
}

}  // namespace superdyna::sim

#include "superdyna/imu/preintegration.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "superdyna/core/error.h"
#include "superdyna/core/geometry.h"

namespace superdyna::imu {

namespace {

void requirePositive(double value, const char* name) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw OptionError(name, "must be a positive finite number");
  }
}

/// Raw IMU signal at one time.
struct Signal {
  Eigen::Vector3d gyro;
  Eigen::Vector3d accel;
};

/// The linear interpolation of the samples at t_ns; the nearest sample outside their range.
Signal signalAt(std::span<const sensors::ImuSample> samples, TimeNs t_ns) {
  if (t_ns <= samples.front().t_ns) return {samples.front().gyro, samples.front().accel};
  if (t_ns >= samples.back().t_ns) return {samples.back().gyro, samples.back().accel};
  const auto after =
      std::upper_bound(samples.begin(), samples.end(), t_ns,
                       [](TimeNs t, const sensors::ImuSample& sample) { return t < sample.t_ns; });
  const sensors::ImuSample& s1 = *after;
  const sensors::ImuSample& s0 = *(after - 1);
  const double u = static_cast<double>(t_ns - s0.t_ns) / static_cast<double>(s1.t_ns - s0.t_ns);
  return {(1.0 - u) * s0.gyro + u * s1.gyro, (1.0 - u) * s0.accel + u * s1.accel};
}

Eigen::Matrix3d orthonormalized(const Eigen::Matrix3d& R) {
  return Eigen::Quaterniond(R).normalized().toRotationMatrix();
}

}  // namespace

Eigen::Vector3d gravityVector() {
  return {0.0, 0.0, -kGravity};
}

ImuNoise ImuNoise::fromCalibration(const sensors::ImuCalibration& calibration) {
  ImuNoise noise;
  noise.gyro_noise_density = calibration.gyroscope_noise_density;
  noise.accel_noise_density = calibration.accelerometer_noise_density;
  noise.gyro_random_walk = calibration.gyroscope_random_walk;
  noise.accel_random_walk = calibration.accelerometer_random_walk;
  return noise;
}

void ImuNoise::validate() const {
  requirePositive(gyro_noise_density, "gyro_noise_density");
  requirePositive(accel_noise_density, "accel_noise_density");
  requirePositive(gyro_random_walk, "gyro_random_walk");
  requirePositive(accel_random_walk, "accel_random_walk");
}

Matrix6d biasRandomWalkCovariance(const ImuNoise& noise, double dt_s) {
  Matrix6d covariance = Matrix6d::Zero();
  covariance.topLeftCorner<3, 3>().diagonal().setConstant(noise.gyro_random_walk *
                                                          noise.gyro_random_walk * dt_s);
  covariance.bottomRightCorner<3, 3>().diagonal().setConstant(noise.accel_random_walk *
                                                              noise.accel_random_walk * dt_s);
  return covariance;
}

void ReintegrationOptions::validate() const {
  requirePositive(max_gyro_bias_change, "max_gyro_bias_change");
  requirePositive(max_accel_bias_change, "max_accel_bias_change");
}

Preintegration::Preintegration(const Bias& linearization_bias, const ImuNoise& noise)
    : linearization_bias_(linearization_bias), noise_(noise) {
  noise_.validate();
  if (!linearization_bias.bg.allFinite() || !linearization_bias.ba.allFinite()) {
    throw OptionError("linearization_bias", "must be finite");
  }
}

void Preintegration::integrate(const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel,
                               double dt_s) {
  requirePositive(dt_s, "dt_s");
  if (!gyro.allFinite()) throw OptionError("gyro", "must be finite");
  if (!accel.allFinite()) throw OptionError("accel", "must be finite");
  if (steps_released_) throw std::logic_error("Preintegration::integrate after releaseSteps()");
  steps_.push_back({gyro, accel, dt_s});
  propagate(steps_.back());
}

void Preintegration::integrateBetween(std::span<const sensors::ImuSample> samples, TimeNs t0_ns,
                                      TimeNs t1_ns) {
  if (t1_ns <= t0_ns) throw OptionError("t1_ns", "must be after t0_ns");
  if (samples.empty()) throw OptionError("samples", "must not be empty");
  for (std::size_t k = 1; k < samples.size(); ++k) {
    if (samples[k].t_ns <= samples[k - 1].t_ns) {
      throw OptionError("samples", "times must be strictly increasing");
    }
  }
  // Break points: t0, every sample time strictly inside (t0, t1), t1.
  auto next =
      std::upper_bound(samples.begin(), samples.end(), t0_ns,
                       [](TimeNs t, const sensors::ImuSample& sample) { return t < sample.t_ns; });
  TimeNs t_a = t0_ns;
  Signal s_a = signalAt(samples, t_a);
  while (t_a < t1_ns) {
    const TimeNs t_b = (next != samples.end() && next->t_ns < t1_ns) ? next->t_ns : t1_ns;
    const Signal s_b = signalAt(samples, t_b);
    integrate(0.5 * (s_a.gyro + s_b.gyro), 0.5 * (s_a.accel + s_b.accel), nsToSeconds(t_b - t_a));
    t_a = t_b;
    s_a = s_b;
    if (next != samples.end()) ++next;
  }
}

void Preintegration::reset() {
  dt_s_ = 0.0;
  dR_.setIdentity();
  dV_.setZero();
  dP_.setZero();
  covariance_.setZero();
  J_R_bg_.setZero();
  J_V_bg_.setZero();
  J_V_ba_.setZero();
  J_P_bg_.setZero();
  J_P_ba_.setZero();
}

void Preintegration::reintegrate(const Bias& new_linearization_bias) {
  if (steps_released_) throw std::logic_error("Preintegration::reintegrate after releaseSteps()");
  linearization_bias_ = new_linearization_bias;
  reset();
  for (const Step& step : steps_)
    propagate(step);
}

bool Preintegration::biasMovedBeyond(const Bias& bias, const ReintegrationOptions& options) const {
  options.validate();
  return (bias.bg - linearization_bias_.bg).norm() > options.max_gyro_bias_change ||
         (bias.ba - linearization_bias_.ba).norm() > options.max_accel_bias_change;
}

bool Preintegration::reintegrateIfBiasMoved(const Bias& bias, const ReintegrationOptions& options) {
  const bool moved = biasMovedBeyond(bias, options);
  if (moved) reintegrate(bias);
  return moved;
}

void Preintegration::releaseSteps() {
  steps_ = {};
  steps_released_ = true;
}

void Preintegration::propagate(const Step& step) {
  const double dt = step.dt_s;
  const double dt2 = dt * dt;
  const Eigen::Vector3d w = step.gyro - linearization_bias_.bg;   // unbiased rate [rad/s]
  const Eigen::Vector3d a = step.accel - linearization_bias_.ba;  // unbiased force [m/s^2]

  // Rotation over the whole step and over its first half (a is applied at mid-step).
  const Eigen::Vector3d phi = w * dt;
  const Eigen::Matrix3d dR_step = expSO3(phi);
  const Eigen::Matrix3d Jr_step = rightJacobianSO3(phi);
  const Eigen::Matrix3d dR_half = expSO3(0.5 * phi);
  const Eigen::Matrix3d Jr_half = rightJacobianSO3(0.5 * phi);
  const Eigen::Matrix3d dR_mid = dR_ * dR_half;
  const Eigen::Matrix3d dR_mid_a_hat = dR_mid * hat(a);
  // dR_mid(bg + d) ~= dR_mid Exp(J_Rmid_bg d).
  const Eigen::Matrix3d J_Rmid_bg = dR_half.transpose() * J_R_bg_ - 0.5 * dt * Jr_half;

  // Covariance of (dphi, dv, dp): x_{k+1} = A x_k + B n, n = (n_g, n_a) of one step with the
  // discrete covariance density^2 / dt.
  Matrix9d A = Matrix9d::Identity();
  A.block<3, 3>(0, 0) = dR_step.transpose();
  A.block<3, 3>(3, 0) = -dR_mid_a_hat * dR_half.transpose() * dt;
  A.block<3, 3>(6, 0) = -0.5 * dR_mid_a_hat * dR_half.transpose() * dt2;
  A.block<3, 3>(6, 3) = Eigen::Matrix3d::Identity() * dt;
  Eigen::Matrix<double, 9, 6> B = Eigen::Matrix<double, 9, 6>::Zero();
  B.block<3, 3>(0, 0) = Jr_step * dt;
  B.block<3, 3>(3, 0) = -0.5 * dt2 * dR_mid_a_hat * Jr_half;
  B.block<3, 3>(6, 0) = -0.25 * dt2 * dt * dR_mid_a_hat * Jr_half;
  B.block<3, 3>(3, 3) = dR_mid * dt;
  B.block<3, 3>(6, 3) = 0.5 * dR_mid * dt2;
  Eigen::Matrix<double, 6, 1> q;
  const double var_g = noise_.gyro_noise_density * noise_.gyro_noise_density / dt;
  const double var_a = noise_.accel_noise_density * noise_.accel_noise_density / dt;
  q << var_g, var_g, var_g, var_a, var_a, var_a;
  covariance_ = A * covariance_ * A.transpose() + B * q.asDiagonal() * B.transpose();
  covariance_ = 0.5 * (covariance_ + covariance_.transpose()).eval();

  // Bias Jacobians (each update uses the values before this step).
  J_P_ba_ += J_V_ba_ * dt - 0.5 * dR_mid * dt2;
  J_P_bg_ += J_V_bg_ * dt - 0.5 * dR_mid_a_hat * J_Rmid_bg * dt2;
  J_V_ba_ -= dR_mid * dt;
  J_V_bg_ -= dR_mid_a_hat * J_Rmid_bg * dt;
  J_R_bg_ = dR_step.transpose() * J_R_bg_ - Jr_step * dt;

  // Deltas.
  const Eigen::Vector3d dR_mid_a = dR_mid * a;
  dP_ += dV_ * dt + 0.5 * dR_mid_a * dt2;
  dV_ += dR_mid_a * dt;
  dR_ = orthonormalized(dR_ * dR_step);
  dt_s_ += dt;
}

Eigen::Matrix3d Preintegration::correctedDeltaRotation(const Bias& bias) const {
  return dR_ * expSO3(J_R_bg_ * (bias.bg - linearization_bias_.bg));
}

Eigen::Vector3d Preintegration::correctedDeltaVelocity(const Bias& bias) const {
  const Eigen::Vector3d dbg = bias.bg - linearization_bias_.bg;
  const Eigen::Vector3d dba = bias.ba - linearization_bias_.ba;
  return dV_ + J_V_bg_ * dbg + J_V_ba_ * dba;
}

Eigen::Vector3d Preintegration::correctedDeltaPosition(const Bias& bias) const {
  const Eigen::Vector3d dbg = bias.bg - linearization_bias_.bg;
  const Eigen::Vector3d dba = bias.ba - linearization_bias_.ba;
  return dP_ + J_P_bg_ * dbg + J_P_ba_ * dba;
}

NavState Preintegration::predict(const NavState& state_i, const Bias& bias) const {
  const Eigen::Vector3d g_w = gravityVector();
  const Eigen::Matrix3d& R_w_i = state_i.R_w_b;
  NavState state_j;
  state_j.R_w_b = orthonormalized(R_w_i * correctedDeltaRotation(bias));
  state_j.v_w = state_i.v_w + g_w * dt_s_ + R_w_i * correctedDeltaVelocity(bias);
  state_j.p_w = state_i.p_w + state_i.v_w * dt_s_ + 0.5 * g_w * dt_s_ * dt_s_ +
                R_w_i * correctedDeltaPosition(bias);
  return state_j;
}

}  // namespace superdyna::imu

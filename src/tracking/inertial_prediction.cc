#include "superdyna/tracking/inertial_prediction.h"

#include <cmath>

#include "superdyna/core/error.h"

namespace superdyna::tracking {

namespace {

/// Covariance of the body pose predicted by a preintegration ([rotation error in the predicted body
/// frame; position error in the world], optim::PosePrior) from the preintegration covariance on
/// (dphi, dv, dp), the errors of the deltas in the IMU frame. R_w_i_start, R_w_i_end: the IMU
/// orientations at the keyframe and at the predicted time.
imu::Matrix6d bodyPoseCovariance(const imu::Matrix9d& preintegration_covariance,
                                 const Eigen::Matrix3d& R_w_i_start,
                                 const Eigen::Matrix3d& R_w_i_end, const SE3d& T_b_i) {
  // The predicted IMU pose at the end carries the errors (dphi, dv, dp) of the deltas:
  //   R_w_i = R_w_i_end Exp(dphi),  p_w_i = p_w_i_end + R_w_i_start dp   (dv only moves v_w).
  // The body pose T_w_b = T_w_i T_i_b then has
  //   R_w_b = R_w_b_end Exp(R_b_i dphi)                      rotation error R_b_i dphi,
  //   p_w_b = p_w_i + R_w_i t_i_b ~= p_w_b_end + R_w_i_start dp - R_w_i_end hat(t_i_b) dphi,
  // so the body error is J (dphi, dv, dp) with the Jacobian J below, and its covariance J C J^T.
  const Eigen::Vector3d t_i_b = T_b_i.inverse().t;
  Eigen::Matrix<double, 6, 9> J = Eigen::Matrix<double, 6, 9>::Zero();
  J.block<3, 3>(0, 0) = T_b_i.rotation();
  J.block<3, 3>(3, 0) = -R_w_i_end * hat(t_i_b);
  J.block<3, 3>(3, 6) = R_w_i_start;
  return J * preintegration_covariance * J.transpose();
}

}  // namespace

void InertialPriorOptions::validate() const {
  if (!(velocity_sigma > 0.0)) throw OptionError("tracker.imu_prior_velocity_sigma", "must be > 0");
  if (!(position_sigma_m > 0.0)) {
    throw OptionError("tracker.imu_prior_position_sigma_m", "must be > 0");
  }
  if (!(rotation_sigma_deg > 0.0)) {
    throw OptionError("tracker.imu_prior_rotation_sigma_deg", "must be > 0");
  }
}

void ImuSampleBuffer::append(const std::vector<sensors::ImuSample>& samples) {
  for (const sensors::ImuSample& sample : samples) {
    if (samples_.empty() || sample.t_ns > samples_.back().t_ns) samples_.push_back(sample);
  }
}

std::optional<ImuGap> findImuGap(const std::vector<sensors::ImuSample>& samples,
                                 TimeNs max_gap_ns) {
  std::optional<ImuGap> gap;
  for (std::size_t k = 1; k < samples.size(); ++k) {
    if (samples[k].t_ns - samples[k - 1].t_ns > max_gap_ns) {
      gap = ImuGap{samples[k - 1].t_ns, samples[k].t_ns};
    }
  }
  return gap;
}

void ImuSampleBuffer::restartAt(const std::vector<sensors::ImuSample>& samples, TimeNs t_ns) {
  samples_.clear();
  for (const sensors::ImuSample& sample : samples) {
    if (sample.t_ns >= t_ns) samples_.push_back(sample);
  }
}

std::vector<sensors::ImuSample> ImuSampleBuffer::startInterval(TimeNs t_ns) {
  std::vector<sensors::ImuSample> interval = samples_;
  std::size_t first = 0;  // the last sample at or before t_ns
  for (std::size_t k = 0; k < samples_.size(); ++k) {
    if (samples_[k].t_ns <= t_ns) first = k;
  }
  samples_.erase(samples_.begin(), samples_.begin() + static_cast<std::ptrdiff_t>(first));
  return interval;
}

std::vector<sensors::ImuSample> joinImuSamples(const std::vector<sensors::ImuSample>& earlier,
                                               const std::vector<sensors::ImuSample>& later) {
  std::vector<sensors::ImuSample> joined;
  joined.reserve(earlier.size() + later.size());
  for (const sensors::ImuSample& sample : earlier) {
    if (!later.empty() && sample.t_ns >= later.front().t_ns) break;
    joined.push_back(sample);
  }
  joined.insert(joined.end(), later.begin(), later.end());
  return joined;
}

std::optional<InertialPrediction> predictFromKeyFrame(
    const map::KeyFrame& keyframe, const std::vector<sensors::ImuSample>& samples, TimeNs t_ns,
    const SE3d& T_b_i, const imu::ImuNoise& noise, const InertialPriorOptions& options) {
  if (samples.size() < 2 || !(t_ns > keyframe.t_ns) || samples.front().t_ns > keyframe.t_ns ||
      samples.back().t_ns < t_ns) {
    return std::nullopt;
  }
  const imu::Bias bias{keyframe.bg, keyframe.ba};
  imu::Preintegration preintegration(bias, noise);
  preintegration.integrateBetween(samples, keyframe.t_ns, t_ns);
  const SE3d T_w_i = keyframe.T_w_b * T_b_i;
  imu::NavState state;
  state.R_w_b = T_w_i.rotation();
  state.p_w = T_w_i.t;
  state.v_w = keyframe.v_w;
  const imu::NavState next = preintegration.predict(state, bias);

  InertialPrediction prediction;
  prediction.T_w_b = SE3d(Eigen::Quaterniond(next.R_w_b).normalized(), next.p_w) * T_b_i.inverse();
  prediction.v_w = next.v_w;
  // Covariance of [rotation error in the predicted body frame; position error in the world]: the
  // preintegration's, carried into the body frame, plus the keyframe state's uncertainty.
  const double dt = preintegration.deltaTime();
  const double sigma_rad = options.rotation_sigma_deg * M_PI / 180.0;
  const double position_variance = options.position_sigma_m * options.position_sigma_m +
                                   dt * dt * options.velocity_sigma * options.velocity_sigma;
  imu::Matrix6d covariance =
      bodyPoseCovariance(preintegration.covariance(), state.R_w_b, next.R_w_b, T_b_i);
  covariance.topLeftCorner<3, 3>() += sigma_rad * sigma_rad * Eigen::Matrix3d::Identity();
  covariance.bottomRightCorner<3, 3>() += position_variance * Eigen::Matrix3d::Identity();
  prediction.prior.T_w_b = prediction.T_w_b;
  const imu::Matrix6d information = covariance.inverse();
  prediction.prior.information = 0.5 * (information + information.transpose());
  return prediction;
}

}  // namespace superdyna::tracking

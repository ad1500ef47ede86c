#include "superdyna/tracking/inertial_prediction.h"

#include <cmath>

#include "superdyna/core/error.h"

namespace superdyna::tracking {

void InertialPriorOptions::validate() const {
  if (!(velocity_sigma > 0.0)) throw OptionError("tracker.imu_prior_velocity_sigma", "must be > 0");
  if (!(position_sigma_m > 0.0)) {
    throw OptionError("tracker.imu_prior_position_sigma_m", "must be > 0");
  }
  if (!(rotation_sigma_deg > 0.0)) {
    throw OptionError("tracker.imu_prior_rotation_sigma_deg", "must be > 0");
  }
}

void ImuSampleBuffer::append(const std::vector<io::ImuSample>& samples) {
  for (const io::ImuSample& sample : samples) {
    if (samples_.empty() || sample.t_ns > samples_.back().t_ns) samples_.push_back(sample);
  }
}

std::vector<io::ImuSample> ImuSampleBuffer::startInterval(TimeNs t_ns) {
  std::vector<io::ImuSample> interval = samples_;
  std::size_t first = 0;  // the last sample at or before t_ns
  for (std::size_t k = 0; k < samples_.size(); ++k) {
    if (samples_[k].t_ns <= t_ns) first = k;
  }
  samples_.erase(samples_.begin(), samples_.begin() + static_cast<std::ptrdiff_t>(first));
  return interval;
}

std::optional<InertialPrediction> predictFromKeyFrame(const map::KeyFrame& keyframe,
                                                      const std::vector<io::ImuSample>& samples,
                                                      TimeNs t_ns, const SE3d& T_b_i,
                                                      const imu::ImuNoise& noise,
                                                      const InertialPriorOptions& options) {
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
  // Covariance of [rotation error in the predicted body frame; position error in the world].
  const double dt = preintegration.deltaTime();
  const double sigma_rad = options.rotation_sigma_deg * M_PI / 180.0;
  const imu::Matrix9d& c = preintegration.covariance();
  imu::Matrix6d covariance = imu::Matrix6d::Zero();
  covariance.topLeftCorner<3, 3>() =
      c.topLeftCorner<3, 3>() + sigma_rad * sigma_rad * Eigen::Matrix3d::Identity();
  const Eigen::Matrix3d& R_i = state.R_w_b;
  const double position_variance = options.position_sigma_m * options.position_sigma_m +
                                   dt * dt * options.velocity_sigma * options.velocity_sigma;
  covariance.bottomRightCorner<3, 3>() = R_i * c.bottomRightCorner<3, 3>() * R_i.transpose() +
                                         position_variance * Eigen::Matrix3d::Identity();
  prediction.prior.T_w_b = prediction.T_w_b;
  const imu::Matrix6d information = covariance.inverse();
  prediction.prior.information = 0.5 * (information + information.transpose());
  return prediction;
}

}  // namespace superdyna::tracking

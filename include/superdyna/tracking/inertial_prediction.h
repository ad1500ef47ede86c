#pragma once
// Tracking with an initialised IMU: the pose of a new frame is predicted from the newest keyframe's
// optimised state (pose, velocity, biases after the visual-inertial BA) by preintegrating the IMU
// samples since that keyframe, and the prediction enters the motion-only BA as a Gaussian pose
// prior.
//
// Why a pose prior (and not ORB-SLAM3's joint pose-velocity-bias frame optimisation): the frame's
// velocity and bias are not needed between keyframes - every prediction restarts from the newest
// keyframe, whose velocity and biases the VI local BA estimates with all its constraints - so the
// only IMU information the frame pose can use is the predicted pose and its uncertainty. That
// uncertainty is the preintegration covariance (white noise, tiny over < 1 s) plus the
// uncertainty of the keyframe state it starts from: the keyframe velocity error grows into the
// position as sigma_v * dt, and the keyframe pose error adds directly. The prior is therefore
// loose against a well-textured image (mm-level vision) and decisive only when vision is weak.

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/imu/preintegration.h"
#include "superdyna/map/keyframe.h"
#include "superdyna/optim/pose_optimizer.h"
#include "superdyna/sensors/measurements.h"

namespace superdyna::tracking {

/// Uncertainty of the keyframe state the prediction starts from.
struct InertialPriorOptions {
  double velocity_sigma = 0.05;     ///< Keyframe velocity std [m/s], > 0.
  double position_sigma_m = 0.005;  ///< Keyframe position std [m], > 0.
  double rotation_sigma_deg = 0.2;  ///< Keyframe rotation std [deg], > 0.
  void validate() const;
  bool operator==(const InertialPriorOptions&) const = default;
};

struct InertialPrediction {
  SE3d T_w_b;                                     ///< Predicted body pose.
  Eigen::Vector3d v_w = Eigen::Vector3d::Zero();  ///< Predicted IMU velocity [m/s].
  optim::PosePrior prior;                         ///< The pose prior for motion-only BA.
};

/// A stretch without IMU samples: consecutive samples t0_ns < t1_ns farther apart than allowed.
struct ImuGap {
  TimeNs t0_ns = 0;  ///< The last sample before the gap.
  TimeNs t1_ns = 0;  ///< The first sample after it.
  double seconds() const { return nsToSeconds(t1_ns - t0_ns); }
  bool operator==(const ImuGap&) const = default;
};

/// The last pair of consecutive samples (time-ordered) more than max_gap_ns apart, if any.
std::optional<ImuGap> findImuGap(const std::vector<sensors::ImuSample>& samples, TimeNs max_gap_ns);

/// IMU samples collected since the newest keyframe: every frame appends its samples (each frame's
/// run brackets the interval since the previous frame, so consecutive runs overlap by a sample).
class ImuSampleBuffer {
 public:
  /// Appends the samples newer than the last one held.
  void append(const std::vector<sensors::ImuSample>& samples);
  /// Starts a new keyframe interval at t_ns: returns the samples held (bracketing the interval
  /// from the previous keyframe) and keeps only those from the last one at or before t_ns.
  std::vector<sensors::ImuSample> startInterval(TimeNs t_ns);
  void clear() { samples_.clear(); }
  /// Drops every sample held and keeps from `samples` only those at or after t_ns: after an IMU
  /// gap ending at t_ns the held run no longer brackets the newest keyframe, so neither a
  /// prediction nor the next keyframe's preintegration spans the gap.
  void restartAt(const std::vector<sensors::ImuSample>& samples, TimeNs t_ns);
  const std::vector<sensors::ImuSample>& samples() const { return samples_; }

 private:
  std::vector<sensors::ImuSample> samples_;
};

/// One run of samples from two consecutive ones: `earlier` (bracketing an interval that ends where
/// `later`'s starts, KeyFrame::imu_from_previous) up to `later`'s first sample, then `later`.
std::vector<sensors::ImuSample> joinImuSamples(const std::vector<sensors::ImuSample>& earlier,
                                               const std::vector<sensors::ImuSample>& later);

/// Predicts the body pose at t_ns from the keyframe's state and the samples (which must bracket
/// [keyframe.t_ns, t_ns]); nullopt otherwise. T_b_i: IMU pose in the body frame. The prior's
/// covariance is the preintegration covariance carried into the body pose (the IMU's rotation in
/// the body frame, the lever arm through which a rotation error moves the body origin, and the
/// correlation of rotation and position errors) plus the keyframe state's uncertainty (options).
std::optional<InertialPrediction> predictFromKeyFrame(
    const map::KeyFrame& keyframe, const std::vector<sensors::ImuSample>& samples, TimeNs t_ns,
    const SE3d& T_b_i, const imu::ImuNoise& noise, const InertialPriorOptions& options);

}  // namespace superdyna::tracking

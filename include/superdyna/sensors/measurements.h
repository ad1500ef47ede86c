#pragma once
// Measurements as every reader produces them (dataset folders, bags, live sensors) and the
// pipeline consumes them: IMU samples and ground-truth states. Frames of images with their IMU
// samples are sensors::FrameBundle (frame_bundle.h).

#include <Eigen/Core>

#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"

namespace superdyna::sensors {

/// One IMU measurement, in the IMU frame.
struct ImuSample {
  TimeNs t_ns = 0;
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();   ///< Angular velocity, rad/s.
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();  ///< Specific force, m/s^2.
};

/// One ground-truth state of the body frame.
struct GroundTruthState {
  TimeNs t_ns = 0;
  SE3d T_w_b;                                     ///< Pose of the body in the world frame.
  Eigen::Vector3d v_w = Eigen::Vector3d::Zero();  ///< Velocity in the world frame, m/s.
  Eigen::Vector3d bg = Eigen::Vector3d::Zero();   ///< Gyroscope bias, rad/s.
  Eigen::Vector3d ba = Eigen::Vector3d::Zero();   ///< Accelerometer bias, m/s^2.
};

}  // namespace superdyna::sensors

#pragma once
// Conversions between ROS 1 message fields and the project's types, shared by the code that
// includes ROS headers (the bag module's reader and writer, the live node's ROS side). This header
// includes ROS headers itself: only C++17 translation units built against them may include it
// (ROS 1 headers do not compile as C++20; see src/bag/CMakeLists.txt).

#include <geometry_msgs/Pose.h>
#include <geometry_msgs/Vector3.h>
#include <ros/time.h>
#include <sensor_msgs/Imu.h>

#include <cstdint>

#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"
#include "superdyna/sensors/measurements.h"

namespace superdyna::bag {

inline ros::Time rosTime(TimeNs t_ns) {
  ros::Time time;
  time.fromNSec(static_cast<std::uint64_t>(t_ns));
  return time;
}

inline TimeNs stampNs(const ros::Time& stamp) {
  return static_cast<TimeNs>(stamp.sec) * kNsPerSecond + static_cast<TimeNs>(stamp.nsec);
}

inline geometry_msgs::Pose poseMessage(const SE3d& T) {
  geometry_msgs::Pose pose;
  pose.position.x = T.t.x();
  pose.position.y = T.t.y();
  pose.position.z = T.t.z();
  pose.orientation.w = T.q.w();
  pose.orientation.x = T.q.x();
  pose.orientation.y = T.q.y();
  pose.orientation.z = T.q.z();
  return pose;
}

/// The pose of a position and orientation (the quaternion normalised by SE3d).
template <typename Position>
SE3d poseOf(const Position& p, const geometry_msgs::Quaternion& q) {
  return SE3d(Eigen::Quaterniond(q.w, q.x, q.y, q.z), Eigen::Vector3d(p.x, p.y, p.z));
}

inline Eigen::Vector3d vectorOf(const geometry_msgs::Vector3& v) {
  return {v.x, v.y, v.z};
}

inline geometry_msgs::Vector3 vector3Message(const Eigen::Vector3d& v) {
  geometry_msgs::Vector3 out;
  out.x = v.x();
  out.y = v.y();
  out.z = v.z();
  return out;
}

/// An IMU message's stamp, angular velocity and linear acceleration.
inline sensors::ImuSample imuSampleOf(const sensor_msgs::Imu& message) {
  sensors::ImuSample sample;  // C++17 here: no designated initialisers
  sample.t_ns = stampNs(message.header.stamp);
  sample.gyro = vectorOf(message.angular_velocity);
  sample.accel = vectorOf(message.linear_acceleration);
  return sample;
}

}  // namespace superdyna::bag

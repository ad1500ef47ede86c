#pragma once
// Writes an EuRoC-layout sequence folder (a simulated one, or any EuRoC / ASL folder) as a ROS 1
// bag in VIODE's layout, with ROS's rosbag_storage:
//   /cam0/image_raw, /cam1/image_raw      sensor_msgs/Image mono8 (cam1 when the folder is stereo)
//   /cam0/segmentation, /cam1/segmentation sensor_msgs/Image bgr8, one colour per object
//                                          (when the folder has camN/segmentation/, written by
//                                          `superdyna simulate --semantic-color`)
//   /imu0                                  sensor_msgs/Imu (when the folder has imu0/)
//   /odometry                              nav_msgs/Odometry of the body in the world frame (the
//                                          ground truth, when the folder has it)
// Header stamps and record times are the sequence's times; frame ids cam0, cam1, imu0 and world
// (child body). The calibration stays in the folder (VIODE ships it beside its bags, too).

#include <cstddef>
#include <filesystem>
#include <map>
#include <string>

namespace superdyna::bag {

/// Writes the sequence at `sequence` (the folder holding mav0/, or mav0) to `bag`, which must not
/// exist (nothing the user has is overwritten), with chunk `compression` "none", "bz2" or "lz4".
/// Returns the messages written per topic. Throws InputError naming the file on bad input (from
/// the EuRoC reader, or an image that does not decode).
std::map<std::string, std::size_t> writeViodeBag(const std::filesystem::path& sequence,
                                                 const std::filesystem::path& bag,
                                                 const std::string& compression = "lz4");

/// The accelerometer rate of writeOpenlorisBag.
inline constexpr double kOpenlorisAccelRateHz = 62.5;

/// Writes the sequence's left camera and IMU as a bag in OpenLORIS-Scene's RealSense D435i layout,
/// with the accelerometer and the gyroscope published apart as the RealSense driver does:
///   /d400/color/image_raw  sensor_msgs/Image rgb8 (the grey image in all three channels)
///   /d400/gyro/sample      sensor_msgs/Imu, angular velocity only, every IMU sample of the folder
///   /d400/accel/sample     sensor_msgs/Imu, linear acceleration only, at kOpenlorisAccelRateHz
///                          (the T265's rate, the slowest of OpenLORIS's IMUs), stamped 2 ms after
///                          the first IMU sample and every 16 ms on (between gyroscope stamps),
///                          the acceleration interpolated linearly between the folder's samples
/// No ground-truth topic: OpenLORIS ships its ground truth as a separate file (the folder's
/// state_groundtruth_estimate0/data.csv is one). Same rules and errors as writeViodeBag; the
/// folder needs imu0/.
std::map<std::string, std::size_t> writeOpenlorisBag(const std::filesystem::path& sequence,
                                                     const std::filesystem::path& bag,
                                                     const std::string& compression = "lz4");

}  // namespace superdyna::bag

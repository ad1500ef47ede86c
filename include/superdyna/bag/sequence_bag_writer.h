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

}  // namespace superdyna::bag

#pragma once
// Writing ROS 1 bags with ROS's rosbag_storage, message by message, from the project's types
// (sensor_msgs/Image from a cv::Mat, sensor_msgs/Imu, nav_msgs/Odometry of a ground-truth state).
// Header stamps are the given times, and so are the record times unless a record time is given
// (a recorder stores the time a message arrived). The bag is written to FILE.partial and
// renamed when close() succeeds, so an interrupted write leaves no bag that looks complete.

#include <cstddef>
#include <filesystem>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "superdyna/core/time.h"
#include "superdyna/sensors/measurements.h"

namespace superdyna::bag {

/// The channel order a colour image is stored in (sensor_msgs encodings bgr8 / rgb8).
enum class ColourOrder { kBgr, kRgb };

class BagWriter {
 public:
  /// Starts a bag at `file`, which must not exist (InputError); compression "none", "bz2" or
  /// "lz4" (OptionError naming `compression` otherwise).
  BagWriter(const std::filesystem::path& file, const std::string& compression);
  /// Removes the partial file unless close() ran.
  ~BagWriter();
  BagWriter(const BagWriter&) = delete;
  BagWriter& operator=(const BagWriter&) = delete;

  /// A sensor_msgs/Image: CV_8UC1 as mono8, CV_8UC3 (BGR, as OpenCV holds it) as bgr8, or as
  /// rgb8 with its channels swapped.
  void writeImage(const std::string& topic, TimeNs t_ns, const cv::Mat& image,
                  const std::string& frame_id, ColourOrder order = ColourOrder::kBgr);
  void writeImu(const std::string& topic, const sensors::ImuSample& sample,
                const std::string& frame_id, std::optional<TimeNs> record_t_ns = std::nullopt);
  /// nav_msgs/Odometry: the body's pose in the world frame, its world-frame velocity as twist.
  void writeOdometry(const std::string& topic, const sensors::GroundTruthState& state);
  /// geometry_msgs/TransformStamped world -> body (as TUM-VI's motion capture publishes).
  void writeTransform(const std::string& topic, const sensors::GroundTruthState& state);
  /// Finishes the bag and moves it to its name.
  void close();

  /// Messages written per topic.
  const std::map<std::string, std::size_t>& counts() const { return counts_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::map<std::string, std::size_t> counts_;
};

}  // namespace superdyna::bag

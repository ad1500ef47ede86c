#pragma once
// Reader of ROS 1 bag files (format 2.0; chunks uncompressed, bz2 or lz4) through ROS's own
// rosbag_storage library (Debian librosbag-storage-dev), producing the project's measurement types:
// images (sensor_msgs/Image mono8, mono16, rgb8, bgr8; sensor_msgs/CompressedImage JPEG or PNG)
// and IMU samples (sensor_msgs/Imu). Module bag: built only when the ROS libraries are found
// (SUPERDYNA_WITH_ROSBAG); nothing else in the project includes ROS headers.
//
// Times are the messages' header stamps (the sensor's time), not the time the bag recorded them.
// Errors name the bag, the topic and the message index (0-based, in the bag's time order).

#include <cstddef>
#include <filesystem>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "superdyna/core/time.h"
#include "superdyna/sensors/measurements.h"

namespace superdyna::bag {

/// One topic of a bag.
struct BagTopic {
  std::string name;
  std::string type;  ///< e.g. "sensor_msgs/Image".
  std::size_t messages = 0;
};

/// One decoded image message.
struct BagImage {
  TimeNs t_ns = 0;       ///< Header stamp.
  std::string encoding;  ///< The message's encoding ("mono8", ...; "jpeg"/"png" for compressed).
  cv::Mat image;  ///< CV_8UC1 (mono8), CV_16UC1 (mono16) or CV_8UC3 BGR (rgb8, bgr8, compressed).
};

/// Grey 8-bit view of a decoded image (CV_16UC1 scaled by 1/256, colour converted).
cv::Mat toGray8(const cv::Mat& image);

class BagImageStream;

class RosbagReader {
 public:
  /// Opens a bag; InputError naming the file when it is missing or not a readable bag.
  static RosbagReader open(const std::filesystem::path& bag);
  ~RosbagReader();
  RosbagReader(RosbagReader&&) noexcept;
  RosbagReader& operator=(RosbagReader&&) noexcept;

  const std::filesystem::path& path() const;
  /// Every topic with its type and message count, sorted by name (a topic recorded through
  /// several connections is one topic).
  const std::vector<BagTopic>& topics() const;
  /// The topic of this name; InputError naming the bag and listing its topics when absent.
  const BagTopic& topic(const std::string& name) const;

  /// Calls `visit` for every message of an image topic (sensor_msgs/Image or CompressedImage) in
  /// the bag's time order. InputError for another message type, an unsupported encoding, or a
  /// message whose data does not fit its size.
  void forEachImage(const std::string& topic,
                    const std::function<void(std::size_t index, const BagImage&)>& visit) const;
  /// The samples of a sensor_msgs/Imu topic in the bag's order.
  std::vector<sensors::ImuSample> imuSamples(const std::string& topic) const;
  /// The header stamps of an image topic's messages in the bag's order.
  std::vector<TimeNs> imageStamps(const std::string& topic) const;
  /// A ground-truth topic as states in the bag's order: nav_msgs/Odometry (pose; twist linear as
  /// the world-frame velocity), geometry_msgs/PoseStamped or TransformStamped (TUM-VI's
  /// /vrpn_client/raw_transform; pose only); biases zero.
  std::vector<sensors::GroundTruthState> groundTruth(const std::string& topic) const;

 private:
  struct Impl;
  explicit RosbagReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
  friend class BagImageStream;
};

/// The messages of an image topic one at a time, in the bag's order (for sequences too long to
/// hold in memory). The reader must outlive the stream.
class BagImageStream {
 public:
  /// InputError as RosbagReader::forEachImage for a topic that is missing or holds no images.
  BagImageStream(const RosbagReader& reader, const std::string& topic);
  ~BagImageStream();
  BagImageStream(const BagImageStream&) = delete;
  BagImageStream& operator=(const BagImageStream&) = delete;

  /// The next image, or nullopt after the last.
  std::optional<BagImage> next();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace superdyna::bag

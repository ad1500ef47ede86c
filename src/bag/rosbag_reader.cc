#include "superdyna/bag/rosbag_reader.h"

#include <fmt/format.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "superdyna/bag/ros_conversions.h"
#include "superdyna/core/error.h"

namespace superdyna::bag {

namespace fs = std::filesystem;

namespace {

constexpr const char* kImageType = "sensor_msgs/Image";
constexpr const char* kCompressedImageType = "sensor_msgs/CompressedImage";
constexpr const char* kImuType = "sensor_msgs/Imu";
constexpr const char* kOdometryType = "nav_msgs/Odometry";
constexpr const char* kPoseStampedType = "geometry_msgs/PoseStamped";
constexpr const char* kTransformStampedType = "geometry_msgs/TransformStamped";

/// The OpenCV type and channel count of a raw image encoding; type -1 when unsupported.
int cvTypeOf(const std::string& encoding) {
  if (encoding == "mono8" || encoding == "8UC1") return CV_8UC1;
  if (encoding == "mono16" || encoding == "16UC1") return CV_16UC1;
  if (encoding == "rgb8" || encoding == "bgr8" || encoding == "8UC3") return CV_8UC3;
  return -1;
}

cv::Mat decodeRaw(const sensor_msgs::Image& msg, const std::string& where) {
  const int type = cvTypeOf(msg.encoding);
  if (type < 0) {
    throw InputError(
        fmt::format("{}: image encoding '{}' is not supported (mono8, mono16, rgb8, "
                    "bgr8)",
                    where, msg.encoding));
  }
  const std::size_t row_bytes = static_cast<std::size_t>(msg.width) * CV_ELEM_SIZE(type);
  if (msg.width == 0 || msg.height == 0 || msg.step < row_bytes ||
      msg.data.size() < static_cast<std::size_t>(msg.step) * msg.height) {
    throw InputError(fmt::format("{}: {}x{} {} image with step {} does not fit its {} data bytes",
                                 where, msg.width, msg.height, msg.encoding, msg.step,
                                 msg.data.size()));
  }
  if (msg.is_bigendian && CV_ELEM_SIZE1(type) > 1) {
    throw InputError(
        fmt::format("{}: big-endian {} images are not supported", where, msg.encoding));
  }
  const cv::Mat view(static_cast<int>(msg.height), static_cast<int>(msg.width), type,
                     const_cast<std::uint8_t*>(msg.data.data()), msg.step);
  cv::Mat image;
  if (msg.encoding == "rgb8") {
    cv::cvtColor(view, image, cv::COLOR_RGB2BGR);
  } else {
    image = view.clone();
  }
  return image;
}

cv::Mat decodeCompressed(const sensor_msgs::CompressedImage& msg, const std::string& where) {
  const cv::Mat encoded(1, static_cast<int>(msg.data.size()), CV_8UC1,
                        const_cast<std::uint8_t*>(msg.data.data()));
  cv::Mat image = cv::imdecode(encoded, cv::IMREAD_UNCHANGED);
  if (image.empty()) {
    throw InputError(fmt::format("{}: compressed image (format '{}', {} bytes) does not decode",
                                 where, msg.format, msg.data.size()));
  }
  if (image.channels() == 4) cv::cvtColor(image, image, cv::COLOR_BGRA2BGR);
  return image;
}

/// "sensor_msgs/Image" of a compressed format string "png", "rgb8; jpeg compressed bgr8", ...
std::string compressedEncoding(const std::string& format) {
  if (format.find("png") != std::string::npos) return "png";
  if (format.find("jpeg") != std::string::npos || format.find("jpg") != std::string::npos) {
    return "jpeg";
  }
  return format;
}

}  // namespace

cv::Mat toGray8(const cv::Mat& image) {
  cv::Mat gray;
  if (image.type() == CV_8UC1) return image;
  if (image.type() == CV_16UC1) {
    image.convertTo(gray, CV_8UC1, 1.0 / 256.0);
  } else if (image.type() == CV_8UC3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else {
    throw InputError(fmt::format("cannot make a grey image of OpenCV type {}", image.type()));
  }
  return gray;
}

struct RosbagReader::Impl {
  fs::path path;
  rosbag::Bag bag;
  std::vector<BagTopic> topics;

  std::string where(const std::string& topic, std::size_t index) const {
    return fmt::format("{}, topic {}, message {}", path.string(), topic, index);
  }
};

RosbagReader::RosbagReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
RosbagReader::~RosbagReader() = default;
RosbagReader::RosbagReader(RosbagReader&&) noexcept = default;
RosbagReader& RosbagReader::operator=(RosbagReader&&) noexcept = default;

RosbagReader RosbagReader::open(const fs::path& bag) {
  std::error_code ec;
  if (fs::is_directory(bag, ec)) {
    throw InputError(InputLocation{bag}, "a folder, not a ROS 1 bag file");
  }
  if (!fs::is_regular_file(bag, ec)) {
    throw InputError(InputLocation{bag}, "bag file not found");
  }
  auto impl = std::make_unique<Impl>();
  impl->path = bag;
  try {
    impl->bag.open(bag.string(), rosbag::bagmode::Read);
    rosbag::View view(impl->bag);
    std::map<std::string, BagTopic> by_name;
    for (const rosbag::ConnectionInfo* connection : view.getConnections()) {
      BagTopic& topic = by_name[connection->topic];
      topic.name = connection->topic;
      topic.type = connection->datatype;
    }
    for (const rosbag::MessageInstance& message : view)
      ++by_name[message.getTopic()].messages;
    for (auto& [name, topic] : by_name)
      impl->topics.push_back(std::move(topic));
  } catch (const rosbag::BagException& e) {
    throw InputError(InputLocation{bag}, fmt::format("not a readable ROS 1 bag: {}", e.what()));
  }
  return RosbagReader(std::move(impl));
}

const fs::path& RosbagReader::path() const {
  return impl_->path;
}

const std::vector<BagTopic>& RosbagReader::topics() const {
  return impl_->topics;
}

const BagTopic& RosbagReader::topic(const std::string& name) const {
  for (const BagTopic& topic : impl_->topics)
    if (topic.name == name) return topic;
  std::string names;
  for (const BagTopic& topic : impl_->topics)
    names += (names.empty() ? "" : ", ") + topic.name;
  throw InputError(InputLocation{impl_->path},
                   fmt::format("no topic '{}' (the bag has: {})", name, names));
}

namespace {

/// One image message decoded; InputError naming `where` for anything else.
BagImage decodeImageMessage(const rosbag::MessageInstance& message, const std::string& where) {
  BagImage out;
  if (const auto raw = message.instantiate<sensor_msgs::Image>()) {
    out.t_ns = stampNs(raw->header.stamp);
    out.encoding = raw->encoding;
    out.image = decodeRaw(*raw, where);
  } else if (const auto compressed = message.instantiate<sensor_msgs::CompressedImage>()) {
    out.t_ns = stampNs(compressed->header.stamp);
    out.encoding = compressedEncoding(compressed->format);
    out.image = decodeCompressed(*compressed, where);
  } else {
    throw InputError(
        fmt::format("{}: {} does not deserialise as an image", where, message.getDataType()));
  }
  return out;
}

/// The header stamp of an image message without decoding its pixels.
TimeNs imageStamp(const rosbag::MessageInstance& message, const std::string& where) {
  if (const auto raw = message.instantiate<sensor_msgs::Image>()) return stampNs(raw->header.stamp);
  if (const auto compressed = message.instantiate<sensor_msgs::CompressedImage>()) {
    return stampNs(compressed->header.stamp);
  }
  throw InputError(
      fmt::format("{}: {} does not deserialise as an image", where, message.getDataType()));
}

void requireType(const BagTopic& topic, const fs::path& bag,
                 std::initializer_list<const char*> types) {
  std::string listed;
  for (const char* type : types) {
    if (topic.type == type) return;
    listed += fmt::format("{}{}", listed.empty() ? "" : " or ", type);
  }
  throw InputError(InputLocation{bag},
                   fmt::format("topic {} holds {}, not {}", topic.name, topic.type, listed));
}

}  // namespace

void RosbagReader::forEachImage(
    const std::string& name,
    const std::function<void(std::size_t index, const BagImage&)>& visit) const {
  BagImageStream stream(*this, name);
  std::size_t index = 0;
  while (const std::optional<BagImage> image = stream.next())
    visit(index++, *image);
}

std::vector<TimeNs> RosbagReader::imageStamps(const std::string& name) const {
  requireType(topic(name), impl_->path, {kImageType, kCompressedImageType});
  std::vector<TimeNs> stamps;
  try {
    rosbag::View view(impl_->bag, rosbag::TopicQuery(name));
    for (const rosbag::MessageInstance& message : view)
      stamps.push_back(imageStamp(message, impl_->where(name, stamps.size())));
  } catch (const rosbag::BagException& e) {
    throw InputError(InputLocation{impl_->path}, fmt::format("topic {}: {}", name, e.what()));
  }
  return stamps;
}

namespace {

/// A ground-truth message (nav_msgs/Odometry, geometry_msgs/PoseStamped or TransformStamped) as a
/// state; nullopt when it is none of them.
std::optional<sensors::GroundTruthState> groundTruthState(const rosbag::MessageInstance& message) {
  sensors::GroundTruthState state;
  if (const auto odometry = message.instantiate<nav_msgs::Odometry>()) {
    state.t_ns = stampNs(odometry->header.stamp);
    state.T_w_b = poseOf(odometry->pose.pose.position, odometry->pose.pose.orientation);
    state.v_w = vectorOf(odometry->twist.twist.linear);
  } else if (const auto pose = message.instantiate<geometry_msgs::PoseStamped>()) {
    state.t_ns = stampNs(pose->header.stamp);
    state.T_w_b = poseOf(pose->pose.position, pose->pose.orientation);
  } else if (const auto transform = message.instantiate<geometry_msgs::TransformStamped>()) {
    state.t_ns = stampNs(transform->header.stamp);
    state.T_w_b = poseOf(transform->transform.translation, transform->transform.rotation);
  } else {
    return std::nullopt;
  }
  return state;
}

}  // namespace

std::vector<sensors::GroundTruthState> RosbagReader::groundTruth(const std::string& name) const {
  requireType(topic(name), impl_->path, {kOdometryType, kPoseStampedType, kTransformStampedType});
  std::vector<sensors::GroundTruthState> states;
  try {
    rosbag::View view(impl_->bag, rosbag::TopicQuery(name));
    for (const rosbag::MessageInstance& message : view) {
      std::optional<sensors::GroundTruthState> state = groundTruthState(message);
      if (!state) {
        throw InputError(fmt::format("{}: {} does not deserialise as a pose",
                                     impl_->where(name, states.size()), message.getDataType()));
      }
      states.push_back(*state);
    }
  } catch (const rosbag::BagException& e) {
    throw InputError(InputLocation{impl_->path}, fmt::format("topic {}: {}", name, e.what()));
  }
  return states;
}

struct BagImageStream::Impl {
  const RosbagReader::Impl* reader = nullptr;
  std::string topic;
  std::unique_ptr<rosbag::View> view;
  rosbag::View::iterator it;
  std::size_t index = 0;
};

BagImageStream::BagImageStream(const RosbagReader& reader, const std::string& topic)
    : impl_(std::make_unique<Impl>()) {
  requireType(reader.topic(topic), reader.path(), {kImageType, kCompressedImageType});
  impl_->reader = reader.impl_.get();
  impl_->topic = topic;
  try {
    impl_->view = std::make_unique<rosbag::View>(reader.impl_->bag, rosbag::TopicQuery(topic));
    impl_->it = impl_->view->begin();
  } catch (const rosbag::BagException& e) {
    throw InputError(InputLocation{reader.path()}, fmt::format("topic {}: {}", topic, e.what()));
  }
}

BagImageStream::~BagImageStream() = default;

std::optional<BagImage> BagImageStream::next() {
  try {
    if (impl_->it == impl_->view->end()) return std::nullopt;
    BagImage image =
        decodeImageMessage(*impl_->it, impl_->reader->where(impl_->topic, impl_->index));
    ++impl_->it;
    ++impl_->index;
    return image;
  } catch (const rosbag::BagException& e) {
    throw InputError(InputLocation{impl_->reader->path},
                     fmt::format("topic {}: {}", impl_->topic, e.what()));
  }
}

std::vector<sensors::ImuSample> RosbagReader::imuSamples(const std::string& name) const {
  requireType(topic(name), impl_->path, {kImuType});
  std::vector<sensors::ImuSample> samples;
  try {
    rosbag::View view(impl_->bag, rosbag::TopicQuery(name));
    for (const rosbag::MessageInstance& message : view) {
      const auto imu = message.instantiate<sensor_msgs::Imu>();
      if (!imu) {
        throw InputError(fmt::format("{}: does not deserialise as {}",
                                     impl_->where(name, samples.size()), kImuType));
      }
      samples.push_back(imuSampleOf(*imu));
    }
  } catch (const rosbag::BagException& e) {
    throw InputError(InputLocation{impl_->path}, fmt::format("topic {}: {}", name, e.what()));
  }
  return samples;
}

}  // namespace superdyna::bag

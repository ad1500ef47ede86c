#include "superdyna/bag/bag_writer.h"

#include <fmt/format.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <opencv2/imgproc.hpp>

#include "superdyna/bag/ros_conversions.h"
#include "superdyna/core/error.h"

namespace superdyna::bag {

namespace fs = std::filesystem;

namespace {

std_msgs::Header header(TimeNs t_ns, const std::string& frame) {
  std_msgs::Header h;
  h.stamp = rosTime(t_ns);
  h.frame_id = frame;
  return h;
}

sensor_msgs::Image imageMessage(const cv::Mat& bgr_or_grey, TimeNs t_ns, const std::string& frame,
                                ColourOrder order) {
  cv::Mat image = bgr_or_grey;
  if (image.channels() == 3 && order == ColourOrder::kRgb)
    cv::cvtColor(bgr_or_grey, image, cv::COLOR_BGR2RGB);
  sensor_msgs::Image msg;
  msg.header = header(t_ns, frame);
  msg.width = static_cast<std::uint32_t>(image.cols);
  msg.height = static_cast<std::uint32_t>(image.rows);
  msg.encoding = image.channels() == 1 ? "mono8" : order == ColourOrder::kRgb ? "rgb8" : "bgr8";
  msg.is_bigendian = 0;
  msg.step = static_cast<std::uint32_t>(image.cols * image.elemSize());
  msg.data.resize(static_cast<std::size_t>(msg.step) * msg.height);
  for (int r = 0; r < image.rows; ++r)
    std::copy(image.ptr<std::uint8_t>(r), image.ptr<std::uint8_t>(r) + msg.step,
              msg.data.begin() + static_cast<std::ptrdiff_t>(r) * msg.step);
  return msg;
}

sensor_msgs::Imu imuMessage(const sensors::ImuSample& sample, const std::string& frame) {
  sensor_msgs::Imu msg;
  msg.header = header(sample.t_ns, frame);
  msg.orientation_covariance[0] = -1.0;  // no orientation estimate
  msg.angular_velocity = vector3Message(sample.gyro);
  msg.linear_acceleration = vector3Message(sample.accel);
  return msg;
}

nav_msgs::Odometry odometryMessage(const sensors::GroundTruthState& state) {
  nav_msgs::Odometry msg;
  msg.header = header(state.t_ns, "world");
  msg.child_frame_id = "body";
  msg.pose.pose = poseMessage(state.T_w_b);
  msg.twist.twist.linear = vector3Message(state.v_w);  // world frame, as the ground truth has it
  return msg;
}

geometry_msgs::TransformStamped transformMessage(const sensors::GroundTruthState& state) {
  geometry_msgs::TransformStamped msg;
  msg.header = header(state.t_ns, "world");
  msg.child_frame_id = "body";
  msg.transform.translation = vector3Message(state.T_w_b.t);
  msg.transform.rotation = poseMessage(state.T_w_b).orientation;
  return msg;
}

rosbag::compression::CompressionType compressionOf(const std::string& name) {
  if (name == "bz2") return rosbag::compression::BZ2;
  if (name == "lz4") return rosbag::compression::LZ4;
  return rosbag::compression::Uncompressed;
}

}  // namespace

struct BagWriter::Impl {
  fs::path file, partial;
  rosbag::Bag bag;
  bool closed = false;
};

BagWriter::BagWriter(const fs::path& file, const std::string& compression)
    : impl_(std::make_unique<Impl>()) {
  if (compression != "none" && compression != "bz2" && compression != "lz4") {
    throw OptionError("compression",
                      fmt::format("expected none, bz2 or lz4, got '{}'", compression));
  }
  std::error_code ec;
  if (fs::exists(file, ec)) {
    throw InputError(InputLocation{file}, "exists already; a bag is never overwritten");
  }
  impl_->file = file;
  impl_->partial = file.string() + ".partial";
  try {
    impl_->bag.open(impl_->partial.string(), rosbag::bagmode::Write);
  } catch (const rosbag::BagException& e) {
    throw InputError(InputLocation{file}, fmt::format("cannot write a bag: {}", e.what()));
  }
  impl_->bag.setCompression(compressionOf(compression));
}

BagWriter::~BagWriter() {
  if (impl_->closed) return;
  try {
    impl_->bag.close();
  } catch (...) {
  }
  std::error_code ec;
  fs::remove(impl_->partial, ec);
}

void BagWriter::writeImage(const std::string& topic, TimeNs t_ns, const cv::Mat& image,
                           const std::string& frame_id, ColourOrder order) {
  if (image.type() != CV_8UC1 && image.type() != CV_8UC3) {
    throw InputError(fmt::format("{}: images must be CV_8UC1 or CV_8UC3, got OpenCV type {}", topic,
                                 image.type()));
  }
  impl_->bag.write(topic, rosTime(t_ns), imageMessage(image, t_ns, frame_id, order));
  ++counts_[topic];
}

void BagWriter::writeImu(const std::string& topic, const sensors::ImuSample& sample,
                         const std::string& frame_id, std::optional<TimeNs> record_t_ns) {
  impl_->bag.write(topic, rosTime(record_t_ns.value_or(sample.t_ns)), imuMessage(sample, frame_id));
  ++counts_[topic];
}

void BagWriter::writeOdometry(const std::string& topic, const sensors::GroundTruthState& state) {
  impl_->bag.write(topic, rosTime(state.t_ns), odometryMessage(state));
  ++counts_[topic];
}

void BagWriter::writeTransform(const std::string& topic, const sensors::GroundTruthState& state) {
  impl_->bag.write(topic, rosTime(state.t_ns), transformMessage(state));
  ++counts_[topic];
}

void BagWriter::close() {
  try {
    impl_->bag.close();
  } catch (const rosbag::BagException& e) {
    throw InputError(InputLocation{impl_->file},
                     fmt::format("writing the bag failed: {}", e.what()));
  }
  fs::rename(impl_->partial, impl_->file);
  impl_->closed = true;
}

}  // namespace superdyna::bag

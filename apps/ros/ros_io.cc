#include "ros_io.h"

#include <cv_bridge/cv_bridge.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/image_encodings.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_ros/transform_broadcaster.h>

#include <algorithm>
#include <atomic>
#include <mutex>
#include <set>

#include "superdyna/bag/ros_conversions.h"

namespace superdyna::ros_node {

using bag::poseMessage;
using bag::rosTime;
using bag::stampNs;

struct RosIo::Impl {
  std::unique_ptr<ros::NodeHandle> node;
  std::unique_ptr<ros::NodeHandle> private_node;
  std::vector<ros::Subscriber> subscribers;
  std::unique_ptr<ros::AsyncSpinner> spinner;
  ros::Publisher odometry, path, map_points, overlay;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf;
  std::string world_frame, body_frame;
  nav_msgs::Path path_message;
  std::size_t poses_seen = 0;
  std::atomic<std::size_t> conversion_errors{0};
  std::mutex reported_mutex;
  std::set<std::string> reported_topics;

  /// The image in `encoding` (mono8 or bgr8), or an empty matrix (counted, reported once per
  /// topic).
  cv::Mat converted(const sensor_msgs::ImageConstPtr& message, const std::string& topic,
                    const std::string& encoding) {
    try {
      return cv_bridge::toCvCopy(message, encoding)->image;
    } catch (const cv_bridge::Exception& e) {
      ++conversion_errors;
      const std::lock_guard lock(reported_mutex);
      if (reported_topics.insert(topic).second) {
        ROS_ERROR(
            "%s: image encoding '%s' cannot be converted to %s (%s); such images are "
            "skipped",
            topic.c_str(), message->encoding.c_str(), encoding.c_str(), e.what());
      }
      return {};
    }
  }

  /// Subscribes to an image topic, handing on the converted images with their header stamps.
  void subscribeImages(const std::string& topic, int camera, const std::string& encoding,
                       const std::function<void(int, TimeNs, const cv::Mat&)>& handler) {
    constexpr std::uint32_t kQueue = 200;  // messages roscpp buffers before dropping
    subscribers.push_back(node->subscribe<sensor_msgs::Image>(
        topic, kQueue,
        [this, camera, topic, encoding, handler](const sensor_msgs::ImageConstPtr& message) {
          const cv::Mat image = converted(message, topic, encoding);
          if (!image.empty()) handler(camera, stampNs(message->header.stamp), image);
        }));
  }
};

RosIo::RosIo(int argc, char** argv, const std::string& node_name)
    : impl_(std::make_unique<Impl>()) {
  ros::init(argc, argv, node_name);
  impl_->node = std::make_unique<ros::NodeHandle>();
  impl_->private_node = std::make_unique<ros::NodeHandle>("~");
}

RosIo::~RosIo() {
  if (impl_->spinner) impl_->spinner->stop();
}

std::string RosIo::param(const std::string& name, const std::string& fallback) const {
  std::string value;
  return impl_->private_node->param(name, value, fallback) ? value : fallback;
}

int RosIo::param(const std::string& name, int fallback) const {
  int value = fallback;
  impl_->private_node->param(name, value, fallback);
  return value;
}

double RosIo::param(const std::string& name, double fallback) const {
  double value = fallback;
  impl_->private_node->param(name, value, fallback);
  return value;
}

bool RosIo::param(const std::string& name, bool fallback) const {
  bool value = fallback;
  impl_->private_node->param(name, value, fallback);
  return value;
}

void RosIo::subscribe(const Subscriptions& topics, ImageHandler on_image, ImuHandler on_imu,
                      SegmentationHandler on_segmentation) {
  const std::string cameras[2] = {topics.cam0, topics.cam1};
  for (int camera = 0; camera < 2; ++camera) {
    if (!cameras[camera].empty()) {
      impl_->subscribeImages(cameras[camera], camera, sensor_msgs::image_encodings::MONO8,
                             on_image);
    }
    if (!topics.segmentation[camera].empty() && on_segmentation) {
      impl_->subscribeImages(topics.segmentation[camera], camera,
                             sensor_msgs::image_encodings::BGR8, on_segmentation);
    }
  }
  if (!topics.imu.empty()) {
    impl_->subscribers.push_back(impl_->node->subscribe<sensor_msgs::Imu>(
        topics.imu, 2000,
        [on_imu](const sensor_msgs::ImuConstPtr& message) { on_imu(bag::imuSampleOf(*message)); }));
  }
  // One callback thread: the handlers see each topic's messages in arrival order.
  impl_->spinner = std::make_unique<ros::AsyncSpinner>(1);
  impl_->spinner->start();
}

void RosIo::advertise(const std::string& world_frame, const std::string& body_frame) {
  impl_->world_frame = world_frame;
  impl_->body_frame = body_frame;
  impl_->odometry = impl_->private_node->advertise<nav_msgs::Odometry>("odometry", 100);
  impl_->path = impl_->private_node->advertise<nav_msgs::Path>("path", 2, /*latch=*/true);
  impl_->map_points =
      impl_->private_node->advertise<sensor_msgs::PointCloud2>("map_points", 2, /*latch=*/true);
  impl_->overlay = impl_->private_node->advertise<sensor_msgs::Image>("overlay", 2);
  impl_->tf = std::make_unique<tf2_ros::TransformBroadcaster>();
  impl_->path_message.header.frame_id = world_frame;
}

void RosIo::publishPose(TimeNs t_ns, const SE3d& T_w_b, int path_every) {
  nav_msgs::Odometry odometry;
  odometry.header.stamp = rosTime(t_ns);
  odometry.header.frame_id = impl_->world_frame;
  odometry.child_frame_id = impl_->body_frame;
  odometry.pose.pose = poseMessage(T_w_b);
  impl_->odometry.publish(odometry);

  geometry_msgs::TransformStamped transform;
  transform.header = odometry.header;
  transform.child_frame_id = impl_->body_frame;
  transform.transform.translation = bag::vector3Message(T_w_b.t);
  transform.transform.rotation = odometry.pose.pose.orientation;
  impl_->tf->sendTransform(transform);

  // The path keeps every path_every-th pose (its messages grow with the run) and is published
  // when one joins.
  if (impl_->poses_seen++ % static_cast<std::size_t>(std::max(path_every, 1)) != 0) return;
  geometry_msgs::PoseStamped pose;
  pose.header = odometry.header;
  pose.pose = odometry.pose.pose;
  nav_msgs::Path& path = impl_->path_message;
  path.poses.push_back(pose);
  path.header.stamp = odometry.header.stamp;
  impl_->path.publish(path);
}

void RosIo::republishPath(const std::vector<std::pair<TimeNs, SE3d>>& poses) {
  nav_msgs::Path& path = impl_->path_message;
  path.poses.clear();
  for (const auto& [t_ns, T_w_b] : poses) {
    geometry_msgs::PoseStamped pose;
    pose.header.stamp = rosTime(t_ns);
    pose.header.frame_id = impl_->world_frame;
    pose.pose = poseMessage(T_w_b);
    path.poses.push_back(pose);
  }
  if (!poses.empty()) path.header.stamp = rosTime(poses.back().first);
  impl_->path.publish(path);
}

void RosIo::publishMapPoints(TimeNs t_ns, const std::vector<ColouredPoint>& points) {
  sensor_msgs::PointCloud2 cloud;
  cloud.header.stamp = rosTime(t_ns);
  cloud.header.frame_id = impl_->world_frame;
  sensor_msgs::PointCloud2Modifier modifier(cloud);
  modifier.setPointCloud2FieldsByString(2, "xyz", "rgb");
  modifier.resize(points.size());
  sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z");
  sensor_msgs::PointCloud2Iterator<std::uint8_t> r(cloud, "r"), g(cloud, "g"), b(cloud, "b");
  for (const ColouredPoint& point : points) {
    *x = static_cast<float>(point.p_w.x());
    *y = static_cast<float>(point.p_w.y());
    *z = static_cast<float>(point.p_w.z());
    *r = point.r;
    *g = point.g;
    *b = point.b;
    ++x, ++y, ++z, ++r, ++g, ++b;
  }
  impl_->map_points.publish(cloud);
}

void RosIo::publishOverlay(TimeNs t_ns, const cv::Mat& bgr) {
  std_msgs::Header header;
  header.stamp = rosTime(t_ns);
  header.frame_id = "cam0";
  impl_->overlay.publish(
      cv_bridge::CvImage(header, sensor_msgs::image_encodings::BGR8, bgr).toImageMsg());
}

bool RosIo::ok() const {
  return ros::ok();
}

std::size_t RosIo::conversionErrors() const {
  return impl_->conversion_errors;
}

bool RosIo::overlayWanted() const {
  return impl_->overlay.getNumSubscribers() > 0;
}

bool RosIo::mapPointsWanted() const {
  return impl_->map_points.getNumSubscribers() > 0;
}

}  // namespace superdyna::ros_node

#pragma once
// The ROS side of the live node superdyna_ros: parameters, subscriptions and publications through
// roscpp, tf2_ros and cv_bridge, behind an interface of the project's types only. ROS 1 headers
// need C++17 (they use std::allocator<void>::rebind, which C++20 removed) while the pipeline's
// headers need C++20, so ros_io.cc is built as C++17 and the node's main as C++20, as the bag
// module does.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <utility>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"
#include "superdyna/sensors/measurements.h"

namespace superdyna::ros_node {

/// Topics to subscribe to; "" = not subscribed.
struct Subscriptions {
  std::string cam0;
  std::string cam1;
  std::string imu;
  std::string segmentation[2];  ///< Colour segmentation images of camera 0 and 1.
};

/// A map point to draw, with its colour.
struct ColouredPoint {
  Eigen::Vector3d p_w;
  std::uint8_t r = 0, g = 0, b = 0;
};

class RosIo {
 public:
  /// A grey image (CV_8UC1; cv_bridge converts colour and 16-bit images) of camera 0 or 1.
  using ImageHandler = std::function<void(int camera, TimeNs t_ns, const cv::Mat& image)>;
  using ImuHandler = std::function<void(const sensors::ImuSample& sample)>;
  /// A colour segmentation image (CV_8UC3 BGR) of camera 0 or 1.
  using SegmentationHandler = std::function<void(int camera, TimeNs t_ns, const cv::Mat& bgr)>;

  /// ros::init with ROS's SIGINT handling (ok() turns false) and the node's handles.
  RosIo(int argc, char** argv, const std::string& node_name);
  ~RosIo();
  RosIo(const RosIo&) = delete;
  RosIo& operator=(const RosIo&) = delete;

  /// The node's private parameter ~name, or `fallback` when it is not set.
  std::string param(const std::string& name, const std::string& fallback) const;
  int param(const std::string& name, int fallback) const;
  bool param(const std::string& name, bool fallback) const;
  double param(const std::string& name, double fallback) const;

  /// Subscribes and starts a spinner thread that calls the handlers. Images that cv_bridge cannot
  /// convert are counted (conversionErrors) and reported once per topic.
  void subscribe(const Subscriptions& topics, ImageHandler on_image, ImuHandler on_imu,
                 SegmentationHandler on_segmentation = {});
  /// Advertises ~odometry (nav_msgs/Odometry), ~path (nav_msgs/Path), ~map_points
  /// (sensor_msgs/PointCloud2, xyz + rgb) and ~overlay (sensor_msgs/Image bgr8), and the tf
  /// `world_frame` -> `body_frame`.
  void advertise(const std::string& world_frame, const std::string& body_frame);

  /// Odometry and tf of the body at t_ns; every `path_every`-th pose joins the path, which is
  /// then published.
  void publishPose(TimeNs t_ns, const SE3d& T_w_b, int path_every);
  /// Replaces the path's poses (after a change of the world frame) and publishes it.
  void republishPath(const std::vector<std::pair<TimeNs, SE3d>>& poses);
  void publishMapPoints(TimeNs t_ns, const std::vector<ColouredPoint>& points);
  void publishOverlay(TimeNs t_ns, const cv::Mat& bgr);

  bool ok() const;
  std::size_t conversionErrors() const;
  /// Subscribers of the overlay and map point topics (drawing is skipped without any).
  bool overlayWanted() const;
  bool mapPointsWanted() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace superdyna::ros_node

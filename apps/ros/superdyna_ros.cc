// superdyna_ros: the SLAM pipeline of `superdyna run` as a live ROS 1 node. It subscribes to the
// camera images and the IMU, assembles frames as the dataset readers serve them
// (io::LiveFrameAssembler), runs them through system::System with the same YAML options file, and
// publishes the body's odometry, path and tf, the map points and an overlay of the keypoints by
// class (dropped ones red). Parameters (private, ~name) are listed in docs/guide/ros-node.md and in
// apps/ros/launch/superdyna.launch. On SIGINT the node finishes local mapping, writes the
// trajectory when ~output is set, prints what it dropped, and exits with 0.

#include <fmt/format.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <mutex>
#include <optional>

#include "live_colour_segmenter.h"
#include "ros_io.h"
#include "superdyna/core/error.h"
#include "superdyna/io/calibration.h"
#include "superdyna/io/live_frame_assembler.h"
#include "superdyna/io/trajectory_io.h"
#include "superdyna/io/vins_calibration.h"
#include "superdyna/semantics/dataset_segmenter.h"
#include "superdyna/semantics/overlay.h"
#include "superdyna/system/frame_overlays.h"
#include "superdyna/system/system.h"

namespace superdyna::ros_node {
namespace {

namespace fs = std::filesystem;

/// The node's parameters.
struct NodeSettings {
  std::string config;       ///< YAML options file ("" = defaults).
  std::string mode;         ///< Sensor mode, as `superdyna run --mode`.
  std::string calibration;  ///< Folder of EuRoC-style sensor.yaml files, or a VINS config file.
  double camera_rate_hz = 20.0;  ///< Rates for a VINS config, which has none.
  double imu_rate_hz = 200.0;
  bool deterministic = false;
  Subscriptions topics;
  std::string world_frame, body_frame;
  std::string output;   ///< Trajectory file (TUM) written at shutdown ("" = none).
  int frame_queue = 2;  ///< Frames waiting for the pipeline; older ones are dropped.
  int overlay_every = 1;
  int map_points_every = 5;  ///< Map points published every N-th keyframe.
  /// semantics.segmenter dataset (format color): the colour segmentation topics, and how long a
  /// frame waits for its segmentation image.
  std::string segmentation_topics[2];
  int segmentation_wait_ms = 300;
};

NodeSettings readSettings(const RosIo& ros) {
  NodeSettings s;
  s.config = ros.param("config", std::string());
  s.mode = ros.param("mode", std::string("stereo-inertial"));
  s.calibration = ros.param("calibration", std::string());
  s.deterministic = ros.param("deterministic", false);
  s.camera_rate_hz = ros.param("camera_rate_hz", 20.0);
  s.imu_rate_hz = ros.param("imu_rate_hz", 200.0);
  s.topics.cam0 = ros.param("cam0_topic", std::string("/cam0/image_raw"));
  s.topics.cam1 = ros.param("cam1_topic", std::string("/cam1/image_raw"));
  s.topics.imu = ros.param("imu_topic", std::string("/imu0"));
  s.world_frame = ros.param("world_frame", std::string("world"));
  s.body_frame = ros.param("body_frame", std::string("body"));
  s.output = ros.param("output", std::string());
  s.frame_queue = ros.param("frame_queue", 2);
  s.overlay_every = ros.param("overlay_every", 1);
  s.map_points_every = ros.param("map_points_every", 5);
  s.segmentation_topics[0] = ros.param("segmentation0_topic", std::string("/cam0/segmentation"));
  s.segmentation_topics[1] = ros.param("segmentation1_topic", std::string("/cam1/segmentation"));
  s.segmentation_wait_ms = ros.param("segmentation_wait_ms", 300);
  if (s.calibration.empty()) {
    throw OptionError("~calibration", "set the folder of the rig's sensor.yaml files");
  }
  if (s.frame_queue < 1) throw OptionError("~frame_queue", "must be >= 1");
  if (s.overlay_every < 1) throw OptionError("~overlay_every", "must be >= 1");
  if (s.map_points_every < 1) throw OptionError("~map_points_every", "must be >= 1");
  return s;
}

system::SystemOptions systemOptions(const NodeSettings& settings) {
  system::SystemOptions options;
  if (!settings.config.empty()) options = system::loadSystemOptions(settings.config);
  options.mode = system::parseSensorMode(settings.mode);
  options.deterministic = settings.deterministic;
  if (options.semantics.segmenter == "dataset" && options.semantics.dataset_format != "color") {
    throw OptionError("semantics.dataset_format",
                      "a live node reads colour segmentation topics (color) or segments with a "
                      "network (semantics.segmenter yolo, maskrcnn, sam)");
  }
  return options;
}

/// Frames from the callbacks to the pipeline: the newest `capacity` wait, older ones are dropped
/// (the pipeline fell behind) and counted; the IMU samples of a dropped frame go to the next one.
class FrameQueue {
 public:
  explicit FrameQueue(std::size_t capacity) : capacity_(capacity) {}

  void push(sensors::FrameBundle bundle) {
    {
      const std::lock_guard lock(mutex_);
      frames_.push_back(std::move(bundle));
      while (frames_.size() > capacity_) {
        io::carrySkippedImu(frames_[0], frames_[1]);  // no motion lost with the frame
        frames_.pop_front();
        ++dropped_;
      }
    }
    ready_.notify_one();
  }

  std::optional<sensors::FrameBundle> pop(std::chrono::milliseconds wait) {
    std::unique_lock lock(mutex_);
    if (!ready_.wait_for(lock, wait, [&] { return !frames_.empty(); })) return std::nullopt;
    sensors::FrameBundle bundle = std::move(frames_.front());
    frames_.pop_front();
    return bundle;
  }

  std::size_t dropped() const {
    const std::lock_guard lock(mutex_);
    return dropped_;
  }

 private:
  std::size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<sensors::FrameBundle> frames_;
  std::size_t dropped_ = 0;
};

/// The callbacks' side: messages into the assembler, complete frames into the queue.
class MessageIntake {
 public:
  MessageIntake(const io::LiveAssemblerOptions& options, FrameQueue& queue)
      : assembler_(options), queue_(queue) {}

  void image(int camera, TimeNs t_ns, const cv::Mat& image) {
    const std::lock_guard lock(mutex_);
    assembler_.addImage(camera, t_ns, image);
    forwardReadyFrames();
  }

  void imu(const sensors::ImuSample& sample) {
    const std::lock_guard lock(mutex_);
    assembler_.addImu(sample);
    forwardReadyFrames();
  }

  io::LiveCounters counters() const {
    const std::lock_guard lock(mutex_);
    return assembler_.counters();
  }

 private:
  void forwardReadyFrames() {
    while (std::optional<sensors::FrameBundle> frame = assembler_.next())
      queue_.push(std::move(*frame));
  }

  mutable std::mutex mutex_;
  io::LiveFrameAssembler assembler_;
  FrameQueue& queue_;
};

std::vector<ColouredPoint> colouredMapPoints(const system::System& slam) {
  std::vector<ColouredPoint> points;
  for (const auto& [p_w, class_id] : slam.mapPointPositions()) {
    const cv::Scalar bgr = semantics::pointColour(class_id);
    points.push_back({p_w, static_cast<std::uint8_t>(bgr[2]), static_cast<std::uint8_t>(bgr[1]),
                      static_cast<std::uint8_t>(bgr[0])});
  }
  return points;
}

bool hasPose(const tracking::TrackingResult& result) {
  return result.state == tracking::TrackingState::kTracking ||
         result.state == tracking::TrackingState::kInitialized ||
         result.state == tracking::TrackingState::kLocalizing;
}

/// Frames per pose of the published path (the odometry has them all).
constexpr int kPathEvery = 10;

/// Publishes what one processed frame gives.
class Publisher {
 public:
  Publisher(RosIo& ros, const NodeSettings& settings, system::FrameOverlays& overlays)
      : ros_(ros), settings_(settings), overlays_(overlays) {}

  void publish(const tracking::TrackingResult& result, const system::System& slam) {
    if (result.world_change) republishPath(result.t_ns, slam);
    if (hasPose(result)) {
      ros_.publishPose(result.t_ns, result.T_w_b, kPathEvery);
      ++published_;
    }
    if (std::optional<system::FrameOverlay> overlay = overlays_.draw(result))
      ros_.publishOverlay(result.t_ns, overlay->image);
    if (result.keyframe && ++keyframes_ % settings_.map_points_every == 0 &&
        ros_.mapPointsWanted()) {
      ros_.publishMapPoints(result.t_ns, colouredMapPoints(slam));
    }
  }

  std::size_t published() const { return published_; }

 private:
  /// The world frame changed (inertial initialisation: gravity, and scale in mono-inertial): the
  /// odometry published so far is in the old frame; the path is re-published in the new one.
  void republishPath(TimeNs t_ns, const system::System& slam) {
    std::vector<std::pair<TimeNs, SE3d>> poses;
    const Trajectory online = slam.onlineTrajectory();
    for (std::size_t i = 0; i < online.size(); i += kPathEvery)
      poses.emplace_back(online[i].t_ns, online[i].T_w_x);
    ros_.republishPath(poses);
    fmt::print(
        "superdyna_ros: world frame changed at {} ns (inertial initialisation); the path is "
        "re-published in the new frame\n",
        t_ns);
    std::fflush(stdout);
  }

  RosIo& ros_;
  const NodeSettings& settings_;
  system::FrameOverlays& overlays_;
  std::size_t published_ = 0;
  int keyframes_ = 0;
};

void printSummary(const system::System& slam, const MessageIntake& intake, const FrameQueue& queue,
                  const Publisher& publisher, const RosIo& ros) {
  const io::LiveCounters c = intake.counters();
  fmt::print(
      "superdyna_ros: {} frames assembled, {} processed, {} poses published; dropped: {} frames "
      "the pipeline was behind, {} images out of order, {} unpaired, {} duplicate, {} not "
      "convertible, {} frames without IMU, {} IMU samples out of order; lost frames {}, map "
      "resets {}\n",
      c.frames, slam.timings().frames, publisher.published(), queue.dropped(),
      c.images_out_of_order, c.images_unpaired, c.duplicate_images, ros.conversionErrors(),
      c.frames_without_imu, c.imu_out_of_order, slam.lostFrames(), slam.resets());
}

int runNode(int argc, char** argv) {
  RosIo ros(argc, argv, "superdyna");
  NodeSettings settings = readSettings(ros);
  const system::SystemOptions options = systemOptions(settings);
  const bool stereo = !system::isMonocular(options.mode);
  const bool inertial = system::usesImu(options.mode);
  io::SensorRig rig = io::readRigCalibration(
      settings.calibration, stereo, inertial,
      {.camera_hz = settings.camera_rate_hz, .imu_hz = settings.imu_rate_hz});
  if (!stereo) settings.topics.cam1.clear();
  if (!inertial) settings.topics.imu.clear();

  // The dataset backend on live topics, or a network, or none.
  LiveColourSegmenter* topic_segmenter = nullptr;
  std::unique_ptr<semantics::Segmenter> segmenter;
  if (options.semantics.segmenter == "dataset") {
    auto live = std::make_unique<LiveColourSegmenter>(
        semantics::readColourTables(options.semantics, settings.calibration),
        settings.segmentation_wait_ms * kNsPerMillisecond);
    topic_segmenter = live.get();
    segmenter = semantics::withPerturbation(options.semantics, std::move(live));
  } else {
    segmenter = semantics::makeSegmenter(options.semantics, settings.calibration);
  }
  if (topic_segmenter) {
    settings.topics.segmentation[0] = settings.segmentation_topics[0];
    if (stereo && options.semantics.right_labels != "left")
      settings.topics.segmentation[1] = settings.segmentation_topics[1];
  }
  system::System slam(options, rig.camera0, rig.camera1, rig.imu, std::move(segmenter));
  system::FrameOverlays overlays(settings.overlay_every,
                                 options.tracker.dynamic.mode != dynamic::DynamicMode::kOff ||
                                     options.tracker.dynamic.geometric,
                                 options.tracker.dynamic);
  slam.setFrontEndCallback([&](const sensors::FrameBundle& bundle, const tracking::Frame& frame) {
    if (ros.overlayWanted()) overlays.remember(bundle, frame);  // drawn only when subscribed
  });
  FrameQueue queue(static_cast<std::size_t>(settings.frame_queue));
  MessageIntake intake({.stereo = stereo, .inertial = inertial}, queue);
  Publisher publisher(ros, settings, overlays);
  ros.advertise(settings.world_frame, settings.body_frame);
  ros.subscribe(
      settings.topics,
      [&](int camera, TimeNs t_ns, const cv::Mat& image) { intake.image(camera, t_ns, image); },
      [&](const sensors::ImuSample& sample) { intake.imu(sample); },
      [&](int camera, TimeNs t_ns, const cv::Mat& bgr) {
        if (topic_segmenter) topic_segmenter->add(camera, t_ns, bgr);
      });
  fmt::print(
      "superdyna_ros: {} SLAM ({}), images {}{}{}{}; publishing ~odometry, ~path, "
      "~map_points, ~overlay and tf {} -> {}\n",
      settings.mode, options.deterministic ? "deterministic" : "concurrent", settings.topics.cam0,
      stereo ? " + " + settings.topics.cam1 : "", inertial ? ", IMU " : "", settings.topics.imu,
      settings.world_frame, settings.body_frame);
  std::fflush(stdout);

  while (ros.ok()) {
    std::optional<sensors::FrameBundle> bundle = queue.pop(std::chrono::milliseconds(100));
    if (!bundle) continue;
    publisher.publish(slam.process(*bundle), slam);
  }
  slam.finish();
  if (!settings.output.empty()) {
    io::writeTrajectory(settings.output, slam.trajectory(), io::TrajectoryFormat::kTum);
    fmt::print("superdyna_ros: wrote {}\n", settings.output);
  }
  printSummary(slam, intake, queue, publisher, ros);
  if (topic_segmenter) {
    fmt::print(
        "superdyna_ros: {} segmentations did not arrive in time (frames taken as all "
        "background)\n",
        topic_segmenter->missing());
  }
  return 0;
}

}  // namespace
}  // namespace superdyna::ros_node

int main(int argc, char** argv) {
  try {
    return superdyna::ros_node::runNode(argc, argv);
  } catch (const std::exception& e) {
    fmt::print(stderr, "superdyna_ros: error: {}\n", e.what());
    return 2;
  }
}

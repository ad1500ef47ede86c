#pragma once
// Reader of the EuRoC MAV / ASL dataset layout:
//
//   mav0/cam0/{sensor.yaml, data.csv, data/<t_ns>.png}    left camera (required)
//   mav0/cam1/...                                          right camera (optional: mono dataset)
//   mav0/imu0/{sensor.yaml, data.csv}                      IMU (optional)
//   mav0/state_groundtruth_estimate0/data.csv              ground truth of the body (optional)
//   mav0/cam{0,1}/mask/<file name of the image>            16-bit instance ids per pixel, 0 =
//                                                          background (optional, simulator)
//   mav0/instances.csv                                     id,class,... per instance (optional)
//
// Everything is read and validated when the dataset is opened (images are only checked to exist);
// bad input throws InputError naming the file, the line and the field. Oddities that do not stop
// the dataset from being used (unpaired stereo frames, IMU gaps, dropped camera frames, IMU rows
// holding nan or inf, which are skipped) are collected in warnings(), naming file and lines.
// Every image the dataset serves (all cam0 frames, the cam1 images of stereo pairs) must exist.
// cam1 rows without a cam0 frame at the same time are never served, so a missing image among them
// is only reported: the shared V1_01 excerpt's cam1/data.csv lists 4 such rows without images.
//
// The streams cover different time ranges: on EuRoC the IMU and the ground truth run far longer
// than an excerpt's images. Use imuBetween() and framesWithImuCoverage() to intersect them.

#include <Eigen/Core>
#include <filesystem>
#include <map>
#include <opencv2/core.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"
#include "superdyna/core/trajectory.h"
#include "superdyna/io/calibration.h"
#include "superdyna/sensors/instance_masks.h"
#include "superdyna/sensors/measurements.h"

namespace superdyna::io {

/// Instance id -> class of a simulator instances.csv ("id,class,..." rows; unlabelled instances
/// left out). InputError naming file, line and field.
std::map<int, int> readInstanceClasses(const std::filesystem::path& csv);

class EurocDataset {
 public:
  /// Opens a sequence: `path` is the sequence folder containing mav0/, or mav0 itself.
  static EurocDataset open(const std::filesystem::path& path);

  /// The mav0 folder.
  const std::filesystem::path& root() const { return root_; }
  /// Whether cam1 exists (then stereoFrames() holds the synchronised pairs).
  bool isStereo() const { return cam1_.has_value(); }
  bool hasImu() const { return imu_calibration_.has_value(); }
  bool hasGroundTruth() const { return !ground_truth_.empty(); }
  /// Whether the sequence has per-camera instance masks and mav0/instances.csv (simulator).
  bool hasInstanceMasks() const { return has_instance_masks_; }
  /// Instance id -> semantic class (sensors::kInstanceClass*) from mav0/instances.csv,
  /// unlabelled instances left out; empty without the file.
  const std::map<int, int>& instanceClasses() const { return instance_classes_; }
  /// The instance mask of an image of this dataset (`image` a path from monoFrames() or
  /// stereoFrames()): mav0/camN/mask/<same file name>, CV_16UC1 of the image's size. Throws
  /// InputError naming the mask file when it is missing, unreadable, of another size or type,
  /// or holds an instance id that instances.csv does not list with a labelled class.
  cv::Mat loadInstanceMask(const std::filesystem::path& image, cv::Size size) const;

  const sensors::CameraCalibration& cam0Calibration() const { return cam0_; }
  /// Empty for a mono dataset.
  const std::optional<sensors::CameraCalibration>& cam1Calibration() const { return cam1_; }
  /// Empty without imu0/.
  const std::optional<sensors::ImuCalibration>& imuCalibration() const { return imu_calibration_; }

  /// Every cam0 frame, in time order.
  const std::vector<ImageRef>& monoFrames() const { return cam0_frames_; }
  /// Frames whose timestamp is in both cam0 and cam1 (exact match), in time order; empty if mono.
  const std::vector<StereoFrameRef>& stereoFrames() const { return stereo_frames_; }
  /// Every IMU sample, in time order; empty without IMU.
  const std::vector<sensors::ImuSample>& imu() const { return imu_; }
  /// Every ground-truth state, in time order; empty without ground truth.
  const std::vector<sensors::GroundTruthState>& groundTruth() const { return ground_truth_; }
  /// False when the ground-truth file has only the pose columns: v_w, bg and ba are then zero.
  bool groundTruthHasVelocityAndBiases() const { return ground_truth_full_state_; }

  /// Time ranges of the streams (first and last sample); empty for an absent stream.
  TimeRange cam0TimeRange() const;
  std::optional<TimeRange> cam1TimeRange() const;
  std::optional<TimeRange> imuTimeRange() const;
  std::optional<TimeRange> groundTruthTimeRange() const;

  /// The IMU samples with t0_ns <= t_ns <= t1_ns (a view into imu(); empty if t1_ns < t0_ns).
  std::span<const sensors::ImuSample> imuBetween(TimeNs t0_ns, TimeNs t1_ns) const;
  /// Whether the IMU stream covers t_ns (first sample <= t_ns <= last sample).
  bool hasImuCoverage(TimeNs t_ns) const;
  /// The stereo frames the IMU covers (those a visual-inertial pipeline can use).
  std::vector<StereoFrameRef> framesWithImuCoverage() const;
  /// The cam0 frames the IMU covers (for mono-inertial use).
  std::vector<ImageRef> monoFramesWithImuCoverage() const;

  /// The ground-truth poses T_w_b as a trajectory (body frame tracked).
  Trajectory groundTruthTrajectory() const;
  /// The ground-truth state closest in time to t_ns, if one lies within max_diff_ns.
  std::optional<sensors::GroundTruthState> groundTruthNearest(TimeNs t_ns,
                                                              TimeNs max_diff_ns) const;

  /// Non-fatal findings of open(): unpaired stereo frames, IMU gaps, dropped cam0 frames, skipped
  /// non-finite IMU rows. One sentence each.
  const std::vector<std::string>& warnings() const { return warnings_; }

 private:
  EurocDataset() = default;

  std::filesystem::path root_;
  sensors::CameraCalibration cam0_;
  std::optional<sensors::CameraCalibration> cam1_;
  std::optional<sensors::ImuCalibration> imu_calibration_;
  std::vector<ImageRef> cam0_frames_;
  std::optional<TimeRange> cam1_range_;  ///< Of every row of cam1/data.csv, paired or not.
  std::vector<StereoFrameRef> stereo_frames_;
  std::vector<sensors::ImuSample> imu_;
  std::vector<sensors::GroundTruthState> ground_truth_;
  bool ground_truth_full_state_ = false;
  bool has_instance_masks_ = false;
  std::map<int, int> instance_classes_;
  std::vector<std::string> warnings_;
};

}  // namespace superdyna::io

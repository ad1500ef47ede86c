#pragma once
// Reader of a KITTI odometry sequence folder:
//
//   image_0/, image_1/   grayscale left/right images (000000.png, ...), or else
//   image_2/, image_3/   colour left/right images, or else
//   image_l/[, image_r/] left (and right) images, as in reduced excerpts
//   calib.txt            3x4 projection matrices, "P0: 12 numbers" a line, or unlabelled lines of
//                        12 numbers in the order P0, P1, P2, P3
//   times.txt            optional: one timestamp in seconds a line (else 10 Hz from 0)
//   poses.txt            optional ground truth: KITTI 3x4 poses of the left camera, one per image
//
// Images are rectified, so the calibration is pinhole without distortion; the body frame is the
// left camera (T_b_c of the left camera is the identity).

#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "superdyna/core/time.h"
#include "superdyna/core/trajectory.h"
#include "superdyna/io/calibration.h"

namespace superdyna::io {

class KittiDataset {
 public:
  /// Opens the sequence folder `dir`. `poses_file` names the ground truth when it is not
  /// dir/poses.txt (the odometry benchmark keeps poses/NN.txt apart from the sequences).
  static KittiDataset open(const std::filesystem::path& dir,
                           const std::optional<std::filesystem::path>& poses_file = std::nullopt);

  const std::filesystem::path& root() const { return root_; }
  /// Whether right images exist (then stereoFrames() holds the pairs).
  bool isStereo() const { return !stereo_frames_.empty(); }
  /// Number of (left) frames.
  std::size_t size() const { return left_frames_.size(); }

  /// The left images in file-name order, with their timestamps.
  const std::vector<ImageRef>& monoFrames() const { return left_frames_; }
  /// Left/right pairs (same file name in both folders); empty without right images.
  const std::vector<StereoFrameRef>& stereoFrames() const { return stereo_frames_; }

  /// Left camera: fx, fy, cx, cy from its projection matrix (P0, or P2 for image_2), size of the
  /// first image, no distortion, rate from the timestamps.
  const sensors::CameraCalibration& leftCalibration() const { return left_; }
  /// Right camera, when calib.txt has its projection matrix (even if its images are absent);
  /// T_b_c is its pose in the left camera frame.
  const std::optional<sensors::CameraCalibration>& rightCalibration() const { return right_; }
  /// Stereo baseline in metres (distance between the optical centres along x), when calib.txt
  /// has the right camera's projection matrix: -P1(0,3) / P1(0,0) for the grayscale pair.
  std::optional<double> baseline() const;

  /// First and last frame time.
  TimeRange timeRange() const { return {left_frames_.front().t_ns, left_frames_.back().t_ns}; }
  /// False when times.txt is absent and the timestamps are the default i * 0.1 s.
  bool hasTimesFile() const { return has_times_file_; }

  bool hasGroundTruth() const { return !ground_truth_.empty(); }
  /// Poses T_w_c of the left camera at the frame times; empty without ground truth.
  const Trajectory& groundTruth() const { return ground_truth_; }

  /// Non-fatal findings of open() (e.g. default timestamps). One sentence each.
  const std::vector<std::string>& warnings() const { return warnings_; }

 private:
  KittiDataset() = default;

  std::filesystem::path root_;
  std::vector<ImageRef> left_frames_;
  std::vector<StereoFrameRef> stereo_frames_;
  sensors::CameraCalibration left_;
  std::optional<sensors::CameraCalibration> right_;
  bool has_times_file_ = false;
  Trajectory ground_truth_;
  std::vector<std::string> warnings_;
};

}  // namespace superdyna::io

#pragma once
// One frame prepared for tracking: the left (cam0) features, their undistorted normalised
// coordinates and, in stereo modes where the stereo matcher found a partner, the depth, the point
// in cam0 and the normalised coordinates of the partner in the right camera; plus the IMU samples
// that bracket the interval since the previous frame.

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "superdyna/core/time.h"
#include "superdyna/features/feature_set.h"
#include "superdyna/sensors/measurements.h"

namespace superdyna::tracking {

struct Frame {
  std::size_t index = 0;  ///< Position in the input sequence.
  TimeNs t_ns = 0;
  features::FeatureSet features;  ///< Left (cam0) features.
  /// Undistorted normalised coordinates per left keypoint; NaN when undistortion failed.
  std::vector<Eigen::Vector2d> normalized;
  std::vector<double> depth_m;        ///< Depth in cam0 per keypoint [m]; -1 = no stereo.
  std::vector<Eigen::Vector3d> p_c0;  ///< Stereo point in cam0 [m] (valid when depth_m > 0).
  std::vector<std::optional<Eigen::Vector2d>> right_normalized;  ///< Partner in cam1, if any.
  std::vector<sensors::ImuSample> imu;  ///< IMU samples bracketing (previous frame, t_ns].
  double extract_ms = 0.0;              ///< Time spent on feature extraction.
  double stereo_ms = 0.0;               ///< Time spent on stereo matching.
  /// Stereo matches whose two keypoints carry different class_id (0 with class-wise matching).
  int cross_class_stereo = 0;

  std::size_t size() const { return features.size(); }
  bool hasStereo(std::size_t i) const { return depth_m[i] > 0.0; }
  int numStereo() const;
  /// The frame with only the keypoints whose `drop` entry is 0 (in order), and every per-keypoint
  /// field with them; the indices kept are appended to `kept` when given.
  Frame withoutKeypoints(const std::vector<char>& drop, std::vector<int>* kept = nullptr) const;
};

}  // namespace superdyna::tracking

#pragma once
// A 3D landmark of the map: its position, a representative descriptor, the keyframes that observe
// it, its semantic label and the viewing geometry used for scale-invariant matching.

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <opencv2/core.hpp>

namespace superdyna::map {

using KeyFrameId = std::int64_t;
using MapPointId = std::int64_t;

/// "No map point" in KeyFrame::map_points, and an unset id.
inline constexpr MapPointId kNoMapPoint = -1;
/// An unset keyframe id.
inline constexpr KeyFrameId kNoKeyFrame = -1;

struct MapPoint {
  MapPointId id = kNoMapPoint;                    ///< Assigned by Map::addMapPoint.
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();  ///< Position in the world frame [m].
  /// One row: 32 bytes (CV_8UC1, ORB) or floats (CV_32FC1, learned descriptors).
  cv::Mat descriptor;

  /// Keyframe id -> index of the observing keypoint in that keyframe. Maintained by Map together
  /// with KeyFrame::map_points; ordered by keyframe id so iteration is deterministic.
  std::map<KeyFrameId, int> observations;

  int class_id = 0;     ///< Semantic class (features::kClass*); 0 = background.
  int instance_id = 0;  ///< Object instance; 0 = static background.

  /// Mean viewing direction: unit vector from the observing camera centres towards the point
  /// (world frame); zero until Map::updateNormalAndDistances.
  Eigen::Vector3d normal_w = Eigen::Vector3d::Zero();
  /// Range of camera distances [m] over which the point can be matched across pyramid levels
  /// (ORB-style scale invariance); 0 until Map::updateNormalAndDistances.
  double min_distance_m = 0.0;
  double max_distance_m = 0.0;

  /// Culled (see Map::setMapPointBad): has no observations and no longer takes new ones.
  bool bad = false;

  int visible_count = 1;  ///< Frames whose view frustum contained the point.
  int found_count = 1;    ///< Frames in which the point was matched.

  /// found_count / visible_count (1 when nothing was counted yet).
  double foundRatio() const {
    return visible_count > 0 ? static_cast<double>(found_count) / visible_count : 1.0;
  }
  int numObservations() const { return static_cast<int>(observations.size()); }
};

}  // namespace superdyna::map

#pragma once
// A 3D landmark of the map: its position, a representative descriptor, the keyframes that observe
// it, its semantic label and the viewing geometry used for scale-invariant matching.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
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

/// ORB-SLAM's view test beyond the image bounds: a camera may see the point only at a distance
/// within [near_factor * min_distance_m, far_factor * max_distance_m] (its scale-invariance range)
/// and from a direction within acos(min_cos_angle) of its mean viewing direction.
struct ViewingLimits {
  double min_cos_angle = 0.5;  ///< 60 degrees.
  double near_factor = 0.8;
  double far_factor = 1.2;
};

/// Whether a camera centred at centre_w passes the point's ViewingLimits. Limits the point does
/// not have yet are not checked: the angle without a normal (normal_w zero), the distance without
/// a range or with an empty one (single-scale extractors, min_distance_m == max_distance_m: their
/// points match over moderate scale changes, nothing bounds them).
inline bool withinViewingLimits(const MapPoint& point, const Eigen::Vector3d& centre_w,
                                const ViewingLimits& limits = {}) {
  const Eigen::Vector3d ray = point.p_w - centre_w;
  const double distance = ray.norm();
  if (!(distance > 0.0)) return false;
  if (point.max_distance_m > point.min_distance_m &&
      (distance < limits.near_factor * point.min_distance_m ||
       distance > limits.far_factor * point.max_distance_m)) {
    return false;
  }
  const double normal_norm = point.normal_w.norm();
  return !(normal_norm > 0.0) ||
         ray.dot(point.normal_w) >= limits.min_cos_angle * distance * normal_norm;
}

/// The pyramid octave at which a camera at `distance` [m] from the point should detect it
/// (ORB-SLAM's MapPoint::PredictScale): ceil(log(max_distance_m / distance) / log(scale_factor))
/// within [0, num_levels - 1]; 0 for a single level or a point without a distance range yet.
inline int predictedOctave(const MapPoint& point, double distance, double scale_factor,
                           int num_levels) {
  if (num_levels <= 1 || !(point.max_distance_m > 0.0) || !(distance > 0.0)) return 0;
  const double octave =
      std::ceil(std::log(point.max_distance_m / distance) / std::log(scale_factor));
  return static_cast<int>(std::clamp(octave, 0.0, static_cast<double>(num_levels - 1)));
}

}  // namespace superdyna::map

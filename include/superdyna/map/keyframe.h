#pragma once
// A keyframe: the state of the body (pose, velocity, IMU biases) at one image time, its keypoints
// and descriptors, and which map point each keypoint observes.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"
#include "superdyna/map/map_point.h"
#include "superdyna/sensors/measurements.h"

namespace superdyna::map {

/// One keypoint of a keyframe.
struct KeyFrameKeypoint {
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  ///< Detected (distorted) position [px].
  /// Undistorted normalised image coordinates (x/z, y/z) in the keypoint's camera: the quantity the
  /// optimisation works with, so lens distortion stays out of it. NaN when the undistortion failed
  /// (far out in a strongly distorted image): the keypoint is then not valid() and is never an
  /// observation (triangulation, BA), though its pixel and descriptor still serve for matching.
  Eigen::Vector2d normalized = Eigen::Vector2d::Zero();
  int octave = 0;       ///< Pyramid level of detection (0 = full resolution).
  float angle = -1.0f;  ///< Orientation [deg] (features::Keypoint::angle); -1 = none.
  int camera = 0;       ///< Camera of the rig that saw it (index into MapOptions::T_b_c).
  int class_id = 0;     ///< Semantic class (features::kClass*); 0 = background.
  int instance_id = 0;  ///< Object instance; 0 = static background.
  /// Rectified stereo: undistorted normalised x of the match in the right camera. Meaningful only
  /// when hasStereo().
  double right_x = 0.0;
  double depth_m = -1.0;  ///< Stereo depth along the camera z axis [m]; negative = none.

  bool hasStereo() const { return depth_m > 0.0; }
  /// Whether the keypoint has normalised coordinates (its undistortion succeeded).
  bool valid() const { return normalized.allFinite(); }
};

struct KeyFrame {
  KeyFrameId id = kNoKeyFrame;  ///< Assigned by Map::addKeyFrame.
  TimeNs t_ns = 0;              ///< Image time [ns].
  SE3d T_w_b;                   ///< Body (IMU) pose in the world frame.
  /// Velocity of the IMU origin in the world frame [m/s] (the body's when T_b_i is identity).
  Eigen::Vector3d v_w = Eigen::Vector3d::Zero();
  Eigen::Vector3d bg = Eigen::Vector3d::Zero();  ///< Gyroscope bias [rad/s].
  Eigen::Vector3d ba = Eigen::Vector3d::Zero();  ///< Accelerometer bias [m/s^2].
  /// Whether an estimation over the map (the inertial initialisation, inertial bundle adjustment:
  /// Map::setKeyFrameInertialState) has set v_w, bg and ba; until then they are the tracker's
  /// prediction at insertion.
  bool inertial_estimated = false;

  /// Temporal predecessor: the keyframe before this one in time, kNoKeyFrame for the first.
  /// Set by Map::addKeyFrame (the newest keyframe of the map) and kept by Map::eraseKeyFrame.
  KeyFrameId previous = kNoKeyFrame;
  /// IMU samples (raw, IMU frame, strictly increasing in time) bracketing [previous.t_ns, t_ns]:
  /// one at or before the predecessor's time, one at or after t_ns. They define the preintegration
  /// from the predecessor (mapping/keyframe_preintegration.h). Empty without IMU. When the
  /// predecessor is erased, Map::eraseKeyFrame prepends its samples, so this always spans the
  /// gap to the current predecessor.
  std::vector<sensors::ImuSample> imu_from_previous;

  std::vector<KeyFrameKeypoint> keypoints;
  cv::Mat descriptors;  ///< Row i describes keypoints[i] (CV_8UC1 or CV_32FC1); may be empty.
  /// Map point observed by keypoints[i], or kNoMapPoint. Maintained by Map together with
  /// MapPoint::observations; Map::addKeyFrame sizes it to keypoints.size().
  std::vector<MapPointId> map_points;

  std::size_t size() const { return keypoints.size(); }
  /// Number of keypoints associated with a map point.
  int numTrackedPoints() const;
};

}  // namespace superdyna::map

#pragma once
// Stereo (optionally IMU-aided) tracking against a local map, sequential and deterministic.
//
// Per frame (built by the FrontEnd: features, stereo depth): pose prediction (constant
// velocity; with IMU samples the rotation comes from gyroscope preintegration), projection of the
// local map (points of the reference keyframe and its best covisible keyframes), matching by
// projection, motion-only BA, keyframe decision, new stereo map points and local BA. Fewer inliers
// than `min_inliers` mark the frame lost; the next frame starts a new map at the predicted pose.

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <unordered_map>
#include <vector>

#include "superdyna/core/camera_model.h"
#include "superdyna/core/geometry.h"
#include "superdyna/features/matcher.h"
#include "superdyna/imu/preintegration.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/map/map.h"
#include "superdyna/mapping/local_mapper.h"
#include "superdyna/optim/pose_optimizer.h"
#include "superdyna/tracking/frame.h"

namespace superdyna::tracking {

struct TrackerOptions {
  features::ProjectionMatchOptions projection;  ///< Map-to-frame matching (radius 15 px).
  double wide_radius_px = 40.0;                 ///< Radius of the retry when too few matches, > 0.
  int min_projection_matches = 40;              ///< Fewer matches trigger the wide retry, >= 0.
  optim::PoseOptimizerOptions pose;             ///< Motion-only BA.
  int min_inliers = 15;                         ///< Fewer pose inliers = tracking lost, >= 3.
  int local_keyframes = 10;  ///< Covisible keyframes whose points form the local map, >= 0.
  double keyframe_tracked_ratio = 0.75;    ///< New keyframe below this share of the ref's points.
  double keyframe_max_interval_s = 0.5;    ///< New keyframe at least this often [s], > 0.
  int keyframe_min_tracked = 150;          ///< New keyframe when fewer inliers than this, >= 0.
  int keyframe_min_stereo = 50;            ///< Stereo keypoints a new keyframe needs, >= 0.
  double close_depth_baselines = 40.0;     ///< New points: depth below this many baselines, > 0.
  int min_new_points = 300;                ///< ... or at least the this many closest stereo points.
  bool stereo_pose_observations = true;    ///< Motion-only BA also uses right-camera points.
  bool imu_translation_prediction = true;  ///< IMU also predicts position (else const. vel.).
  bool use_imu = true;                     ///< Use IMU samples for rotation prediction and gravity.
  /// Weak prior on the IMU-predicted rotation in motion-only BA [deg]; 0 = no prior.
  double imu_rotation_prior_sigma_deg = 0.0;
  void validate() const;
};

enum class TrackingState { kTracking, kInitialized, kLost };
const char* toString(TrackingState state);

struct StageTimes {
  double extract_ms = 0.0;
  double stereo_ms = 0.0;
  double track_ms = 0.0;
  double local_ba_ms = 0.0;
};

struct TrackingResult {
  SE3d T_w_b;  ///< Estimated (or, when lost, predicted) body pose.
  TrackingState state = TrackingState::kLost;
  int matches = 0;
  int cross_class_matches = 0;  ///< Map-to-frame matches between different class_id.
  int inliers = 0;
  bool keyframe = false;
  StageTimes times;
};

/// Scale pyramid of the extractor (map points predict the octave they are seen at).
struct PyramidInfo {
  double scale_factor = 1.2;
  int levels = 8;
};

class Tracker {
 public:
  /// cam1 absent = monocular rig.
  Tracker(const TrackerOptions& options, const PyramidInfo& pyramid,
          const mapping::LocalMapperOptions& mapping, const io::CameraCalibration& cam0,
          const std::optional<io::CameraCalibration>& cam1,
          const std::optional<io::ImuCalibration>& imu);

  /// Tracks one frame built by the FrontEnd (frames in time order).
  TrackingResult track(const Frame& frame);

  const map::Map& map() const { return *map_; }
  int resets() const { return resets_; }

 private:
  struct LocalPoint {
    map::MapPointId id = map::kNoMapPoint;
    Eigen::Vector3d p_w = Eigen::Vector3d::Zero();
  };

  struct Prediction {
    SE3d T_w_b;
    bool from_imu = false;  ///< Rotation from gyroscope preintegration.
  };
  Prediction predictPose(const Frame& frame) const;
  SE3d predictWithImu(const imu::Preintegration& preintegration) const;
  std::optional<optim::PosePrior> rotationPrior(const Prediction& prediction) const;
  SE3d initialPose(const Frame& frame, const SE3d& predicted) const;
  void initializeAt(const Frame& frame, const SE3d& T_w_b, TrackingResult& result);
  void startMap(const Frame& frame, const SE3d& T_w_b);
  std::vector<map::MapPointId> trackLocalMap(const Frame& frame, const Prediction& prediction,
                                             TrackingResult& result);
  void addKeyFrameAndMap(const Frame& frame, const std::vector<map::MapPointId>& tracked,
                         TrackingResult& result);
  std::vector<LocalPoint> localPoints() const;
  std::vector<features::Match> matchLocalPoints(const Frame& frame,
                                                const std::vector<LocalPoint>& points,
                                                const SE3d& T_w_b);
  std::vector<optim::PoseObservation> poseObservations(
      const Frame& frame, const std::vector<LocalPoint>& points,
      const std::vector<features::Match>& matches) const;
  bool needKeyFrame(const Frame& frame, int inliers) const;
  int referenceTrackedPoints() const;
  map::KeyFrameId insertKeyFrame(const Frame& frame, const SE3d& T_w_b,
                                 const std::vector<map::MapPointId>& tracked);
  std::vector<map::MapPointId> createStereoPoints(const Frame& frame, const SE3d& T_w_b,
                                                  map::KeyFrameId keyframe,
                                                  const std::vector<map::MapPointId>& tracked);
  void updateMotion(const SE3d& T_w_b, TimeNs t_ns);

  TrackerOptions options_;
  PyramidInfo pyramid_;
  CameraModel camera0_;
  SE3d T_b_c0_;
  optim::PoseOptimizer pose_optimizer_;
  std::vector<optim::ReprojectionCamera> cameras_;
  std::optional<io::ImuCalibration> imu_;
  imu::Bias bias_;
  double baseline_m_ = 0.0;
  std::unique_ptr<map::Map> map_;
  mapping::LocalMapper mapper_;
  std::unordered_map<map::MapPointId, features::Keypoint> point_keypoint_;  ///< For the query.

  bool has_map_ = false;
  bool has_last_ = false;
  bool has_motion_ = false;
  SE3d T_w_b_last_;
  SE3d motion_;  ///< T_b_last_b_current of the last tracked step.
  bool has_velocity_ = false;
  Eigen::Vector3d velocity_w_ = Eigen::Vector3d::Zero();  ///< Of the IMU origin [m/s].
  TimeNs t_last_ns_ = 0;
  map::KeyFrameId reference_ = map::kNoKeyFrame;
  TimeNs t_reference_ns_ = 0;
  int resets_ = 0;
};

}  // namespace superdyna::tracking

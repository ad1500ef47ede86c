#pragma once
// Stereo (optionally IMU-aided) tracking against a local map, sequential and deterministic.
//
// Per frame (built by the FrontEnd: features, stereo depth): pose prediction (constant
// velocity; with IMU samples the rotation comes from gyroscope preintegration; once local mapping
// has initialised the IMU, preintegration from the newest keyframe's optimised state, used as a
// pose prior too - see inertial_prediction.h), projection of the
// local map (points of the reference keyframe and its best covisible keyframes), matching by
// projection, motion-only BA, keyframe decision, new stereo map points and local BA. Fewer inliers
// than `min_inliers` mark the frame lost: the map is kept and the next frames are relocalised in it
// for relocalization_s, then a frame starts a new map at its predicted pose.
//
// Monocular rigs (no cam1) start each map by two-view initialisation (mono_initializer.h) and get
// new points only from the local mapper's triangulation. With an IMU (mono-inertial) the local
// mapper's inertial initialisation (as for stereo-inertial, with the scale estimated too) makes the
// map metric and gravity-aligned; until then the IMU only predicts rotations. Keyframes of a
// monocular-inertial map are at least imu_min_keyframe_interval_s apart (ORB-SLAM3 inserts them
// every 0.25-0.5 s): more frequent ones add little parallax and cost local BA time. Once the map
// is inertial, a weakly tracked frame becomes a keyframe sooner (imu_weak_keyframes, ORB-SLAM3's
// rule): where the view changes fast, waiting lets the tracked points run out.
//
// Monocular maps with a mapping thread (MappingSink): tracking needs the points the mapper
// triangulates from the previous keyframe, so the tracker never runs more than one keyframe ahead
// of the mapper. When a keyframe is wanted while the mapper still works on the previous one, the
// tracker waits for it and then inserts the keyframe (mono_wait_for_mapping, the default: the
// keyframes are the ones the sequential pipeline would take). Otherwise (ORB-SLAM's real-time
// policy) the keyframe is refused unless tracking is weak (fewer than keyframe_weak_inliers
// inliers) or keyframe_max_interval_s has passed since the last one, and only then waited for.
//
// With a mapping thread each frame reads the map (prediction from the reference keyframe, local
// map, matching, keyframe decision) under the map's read lock, so that it sees a local BA, a
// culling or a triangulation either applied entirely or not at all; it releases the lock before it
// inserts a keyframe (itself one map update) and before anything that waits for the mapper.

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <optional>
#include <set>
#include <unordered_map>
#include <vector>

#include "superdyna/core/camera_model.h"
#include "superdyna/core/geometry.h"
#include "superdyna/dynamic/moving_object_detector.h"
#include "superdyna/features/matcher.h"
#include "superdyna/imu/preintegration.h"
#include "superdyna/map/atlas.h"
#include "superdyna/map/map.h"
#include "superdyna/mapping/local_mapper.h"
#include "superdyna/optim/pose_optimizer.h"
#include "superdyna/sensors/calibration.h"
#include "superdyna/sensors/measurements.h"
#include "superdyna/tracking/frame.h"
#include "superdyna/tracking/inertial_prediction.h"
#include "superdyna/tracking/mono_initializer.h"
#include "superdyna/tracking/reference_matching.h"

namespace superdyna::tracking {

struct TrackerOptions {
  features::ProjectionMatchOptions projection;  ///< Map-to-frame matching (radius 15 px).
  double wide_radius_px = 40.0;                 ///< Radius of the retry when too few matches, > 0.
  int min_projection_matches = 40;              ///< Fewer matches trigger the wide retry, >= 0.
  /// Second search, > 0: after the first pose estimate, the local map is matched again within
  /// this radius [px] of the points' projections from that estimate and the pose optimised again
  /// (kept when it has more inliers). Corrects wrong first matches from a poor prediction, e.g.
  /// of learned features whose 1/8-resolution descriptors barely tell neighbours apart; 0 = off.
  double refine_radius_px = 0.0;
  optim::PoseOptimizerOptions pose;  ///< Motion-only BA.
  int min_inliers = 15;              ///< Fewer pose inliers = tracking lost, >= 3.
  int local_keyframes = 10;          ///< Covisible keyframes whose points form the local map, >= 0.
  double keyframe_tracked_ratio = 0.75;  ///< New keyframe below this share of the ref's points.
  double keyframe_max_interval_s = 0.5;  ///< New keyframe at least this often [s], > 0.
  int keyframe_min_tracked = 150;        ///< New keyframe when fewer inliers than this, >= 0.
  /// No new keyframe sooner than this after the previous one [s], >= 0, unless tracking is weak
  /// (fewer than keyframe_weak_inliers inliers). Monocular maps need it: without a busy mapping
  /// thread (deterministic pipeline) the tracked-ratio test alone fires at almost every frame.
  double keyframe_min_interval_s = 0.0;
  /// Tracking this weak (fewer inliers) overrides keyframe_min_interval_s and, monocular with a
  /// mapping thread, makes the tracker wait for a busy mapper to insert a keyframe, >= 0.
  int keyframe_weak_inliers = 75;
  /// Monocular with a mapping thread: a keyframe wanted while the mapper is busy waits for it
  /// (true) or is refused unless tracking is weak or the last keyframe is overdue (false).
  bool mono_wait_for_mapping = true;
  /// Mono-inertial with a mapping thread: tracking waits for each new keyframe's mapping job.
  /// Once the IMU is initialised, the IMU prediction (and its pose prior) starts from the newest
  /// keyframe's state; unrefined (tracked pose, predicted velocity), it lost track on V1_02.
  /// Before, the keyframe's new points are triangulated there: without them, on a fast turn
  /// tracking ran out of map points (the loop tests' wobbling circle lost track in half the runs).
  bool mono_inertial_wait_for_keyframe_ba = true;
  int keyframe_min_stereo = 50;            ///< Stereo keypoints a new keyframe needs, >= 0.
  double close_depth_baselines = 40.0;     ///< New points: depth below this many baselines, > 0.
  int min_new_points = 300;                ///< ... or at least the this many closest stereo points.
  bool stereo_pose_observations = true;    ///< Motion-only BA also uses right-camera points.
  bool imu_translation_prediction = true;  ///< IMU also predicts position (else const. vel.).
  bool use_imu = true;                     ///< Use IMU samples for rotation prediction and gravity.
  /// Weak prior on the IMU-predicted rotation in motion-only BA [deg]; 0 = no prior. Used until
  /// the inertial initialisation; after it the full pose prior of `imu_prior` applies.
  double imu_rotation_prior_sigma_deg = 0.0;
  MonoInitializerOptions mono_init;  ///< Two-view initialisation of monocular maps.
  /// With IMU, before the inertial initialisation (monocular: always): no new keyframe sooner than
  /// this after the previous one [s], >= 0 (ORB-SLAM3: 0.25 s). Very short keyframe gaps have
  /// near-zero preintegration covariance, so the visual pose noise would dominate the
  /// initialisation.
  double imu_min_keyframe_interval_s = 0.25;
  /// Monocular with IMU, after the inertial initialisation: weak tracking (fewer than
  /// keyframe_weak_inliers inliers) overrides imu_min_keyframe_interval_s, as ORB-SLAM3 inserts a
  /// mono-inertial keyframe whenever fewer than 75 points are tracked. Without it a parking lot
  /// whose movers were removed lost track for good 0.2 s after a keyframe
  /// (docs/concepts/front-end.md).
  bool imu_weak_keyframes = true;
  /// After the inertial initialisation: prediction from the newest keyframe and its pose prior.
  InertialPriorOptions imu_prior;
  /// After the inertial initialisation, tracking failures keep the map and report the IMU
  /// prediction (kRecentlyLost) for up to this long after the last tracked frame [s], >= 0; the
  /// next frames are tracked against the map from the prediction. Only longer failures start a new
  /// map (monocular: at a new, arbitrary scale). 0 = a new map at the first failure. Without
  /// relocalisation the bridge only pays while the IMU prediction still lands within the
  /// projection search radius: 3 s turned one reset on a dim, blurred XFeat run into 61 lost frames
  /// and twice the ATE, so the default covers short dropouts (a few blurred frames) only.
  double imu_bridge_s = 0.5;
  /// A tracking failure (beyond the IMU bridge) keeps the map for up to this long after its first
  /// failed frame [s], >= 0, and each frame is relocalised in it (relocalize()): only when none
  /// is located in time does a new map start. ORB-SLAM3 keeps trying for 3 s (5 s with an IMU);
  /// 0 = a new map at the first failure.
  double relocalization_s = 3.0;
  /// Keyframes a lost frame is located against, >= 1: this many proposed by place recognition
  /// (the loop closer's keyframe database, when loop closing runs), and this many nearest to its
  /// predicted position (the IMU's, else the constant-velocity model's).
  int relocalization_candidates = 8;
  /// Stereo-inertial: a frame beyond the IMU bridge that is neither tracked nor relocalised but
  /// has stereo points (keyframe_min_stereo) becomes a keyframe at the IMU-predicted pose, with
  /// new stereo points, in the same map (within relocalization_s of the last tracked frame, which
  /// bounds the IMU's drift): the preintegration across the failure links it to the keyframes
  /// before, as a visual-inertial odometer carries its state through a blackout. Off: such frames
  /// wait for relocalisation.
  bool imu_reanchor = true;
  /// Consecutive IMU samples farther apart than this [s], > 0, are a gap (a dropped stretch of the
  /// stream): frames whose interval touches it are predicted without the IMU (the gyroscope-free
  /// constant-velocity model), the IMU run restarts after the gap, and the keyframe interval that
  /// spans it gets no preintegration factor (a single step over the gap would be one linearly
  /// interpolated sample, its covariance singular). Inertial tracking resumes from the first
  /// keyframe after the gap. Each gap is reported once (TrackingResult::imu_gap).
  double imu_max_gap_s = 0.1;
  /// Local-map points count as visible to a frame (map::MapPoint::visible_count, the denominator of
  /// culling's found ratio) only from within their viewing limits (map::withinViewingLimits:
  /// ORB-SLAM's distance range and 60-degree viewing angle) or when matched, so that frames that
  /// could not have matched a point do not count against it. All points in the image are still
  /// searched: restricting the search itself (as ORB-SLAM does) lost track once on the 3 s
  /// monocular street flight of tracker_test.
  bool viewing_limits = true;
  /// Local-map points are searched at the octave predicted from their distance
  /// (map::predictedOctave, ORB-SLAM's local-map search) instead of the octave of their oldest
  /// observation; `projection`'s octave window, radius growth and within-octave ratio test apply
  /// to that octave.
  bool predict_octave = false;
  /// Pose from the reference keyframe without a prediction (reference_matching.h): for frames whose
  /// motion is unknown and as a retry before a frame is declared lost.
  ReferenceMatchingOptions reference_matching;
  /// The moving-object test between the pose prediction and the local-map search
  /// (dynamic/moving_object_detector.h): the relative pose of the previous and the current frame
  /// is the tracker's prediction (after the inertial initialisation IMU preintegration from the
  /// newest keyframe, before it the gyroscope's rotation with the constant-velocity translation,
  /// without IMU the constant-velocity model). Dropped keypoints take no part in the pose, create
  /// no map points, and the map points of their partners in the previous frame are culled.
  dynamic::MovingObjectOptions dynamic;
  void validate() const;
  bool operator==(const TrackerOptions&) const = default;
};

/// kInitializing: a monocular map is being initialised; the frame has no pose estimate.
/// kRecentlyLost: tracking failed on a map whose IMU is initialised; the pose is the IMU
/// prediction and the map is kept (ORB-SLAM3's RECENTLY_LOST), see TrackerOptions::imu_bridge_s.
/// kLocalizing: a loaded map (Tracker::localizeIn) in which the frame could not be located yet;
/// the frame has no pose estimate.
enum class TrackingState {
  kTracking,
  kInitialized,
  kLost,
  kInitializing,
  kRecentlyLost,
  kLocalizing
};
const char* toString(TrackingState state);

struct StageTimes {
  double extract_ms = 0.0;
  double stereo_ms = 0.0;
  double track_ms = 0.0;
  double local_ba_ms = 0.0;
  double moving_objects_ms = 0.0;  ///< The moving-object test (part of track_ms).
};

struct TrackingResult {
  TimeNs t_ns = 0;  ///< The frame's time.
  SE3d T_w_b;       ///< Estimated (or, when lost, predicted) body pose.
  /// The predicted pose the frame's search started from (IMU or constant-velocity model), in the
  /// frame of T_w_b (moved with the map's changes at this frame, as T_w_b).
  SE3d T_w_predicted;
  TrackingState state = TrackingState::kLost;
  int matches = 0;
  int cross_class_matches = 0;  ///< Map-to-frame matches between different class_id.
  int inliers = 0;
  /// Tracked from the reference keyframe's PnP pose instead of the prediction
  /// (reference_matching.h).
  bool from_reference = false;
  /// Located again in its map after a tracking failure (TrackerOptions::relocalization_s).
  bool relocalized = false;
  /// Neither tracked nor relocalised: became a keyframe of its map at the IMU-predicted pose
  /// (TrackerOptions::imu_reanchor; state kRecentlyLost).
  bool reanchored = false;
  bool keyframe = false;
  /// The keyframe the pose was estimated against (the frame's own when it became one; for a lost
  /// frame, the reference keyframe its prediction started from, also in a map tracking leaves)
  /// and its pose at that moment, kNoKeyFrame when there is none: the frame's pose relative to it
  /// follows the keyframe's later corrections and merges (System::trajectory).
  map::KeyFrameId reference = map::kNoKeyFrame;
  SE3d T_w_reference;
  /// Set when the world frame of the current map changed at this frame (inertial initialisation:
  /// gravity alignment; mono-inertial: scale too): poses reported earlier on this map map into the
  /// new frame by mapping::transformBodyPose.
  std::optional<Sim3d> world_change;
  /// The moving-object test's decisions (objects empty with dynamic.mode off); drop indexes the
  /// frame's keypoints as the front end built them.
  dynamic::MovingObjectReport moving;
  int culled_moving_points = 0;  ///< Map points culled because their object moves.
  /// An IMU gap (TrackerOptions::imu_max_gap_s) first met at this frame; the frame was predicted
  /// without the IMU.
  std::optional<ImuGap> imu_gap;
  StageTimes times;
};

/// Scale pyramid of the extractor (map points predict the octave they are seen at).
struct PyramidInfo {
  double scale_factor = 1.2;
  int levels = 8;
};

/// Where the tracker sends the local-mapping work of its keyframes (registering a keyframe with the
/// LocalMapper, local BA, resets). Without a sink the tracker runs each job at once, inside
/// track(): the sequential, deterministic pipeline. A sink may run the jobs later in another thread
/// (the concurrent System); it must run them one at a time, in submission order, all in the same
/// thread. The jobs' multi-call map changes are map updates (map::Map::updateLock()); the tracker
/// holds no lock of its map while it calls the sink, so a sink may run jobs inside its calls.
class MappingSink {
 public:
  virtual ~MappingSink() = default;
  /// Queues one job; the job touches the tracker's LocalMapper and map.
  virtual void submit(std::function<void()> job) = 0;
  /// Discards the queued jobs and returns once no job runs any more: the tracker is about to drop
  /// the map (and reset the LocalMapper) that they work on.
  virtual void discardPending() = 0;
  /// Returns once every job submitted so far has run (the map is quiet until the next submit).
  virtual void waitIdle() = 0;
  /// A job is queued or running.
  virtual bool busy() const = 0;
};

/// Told about each keyframe of a map once local mapping has processed it, in the thread that runs
/// the mapping jobs (inside track() without a MappingSink): the loop closer. It may change the
/// map (as one map update) and record the change with map::Map::recordCorrection(); the tracker
/// moves its own state (last pose, velocity) and the poses it reports with it, and after a
/// correction runs the mapper's global BA (mapping::LocalMapper::globalBundleAdjust; with a
/// MappingSink in a thread of its own, startGlobalBundleAdjust, applied by a later mapping job or
/// by finishGlobalBundleAdjust()).
class KeyFrameObserver {
 public:
  virtual ~KeyFrameObserver() = default;
  /// Only for keyframes of maps that will not move as a whole any more: visual maps, and inertial
  /// ones once every inertial (re-)initialisation stage has run (`inertial` then true). Returns
  /// whether it corrected the map (a loop closure).
  virtual bool keyFrameMapped(map::Map& map, map::KeyFrameId id, bool inertial) = 0;
  /// The tracker is about to drop its map: forget everything about it, and return only once no
  /// thread of the observer uses it any more. Called from the tracking thread while no mapping
  /// job runs.
  virtual void mapReset() = 0;
  /// Place recognition for relocalisation: the keyframes seen so far whose places look most like
  /// `frame`'s, best first, at most `count` (none by default). Called from the tracking thread
  /// while the mapping jobs run: must be thread-safe. Ids of a map just dropped may still come
  /// back until mapReset() has run; they simply fail the geometric check.
  virtual std::vector<map::KeyFrameId> recognizePlace(const Frame& frame, int count) const {
    (void)frame;
    (void)count;
    return {};
  }
};

class Tracker {
 public:
  /// cam1 absent = monocular rig.
  Tracker(const TrackerOptions& options, const PyramidInfo& pyramid,
          const mapping::LocalMapperOptions& mapping, const sensors::CameraCalibration& cam0,
          const std::optional<sensors::CameraCalibration>& cam1,
          const std::optional<sensors::ImuCalibration>& imu);

  /// Tracks one frame built by the FrontEnd (frames in time order).
  TrackingResult track(const Frame& frame);

  /// The current map; only valid once hasMap() (a first frame with enough stereo points).
  const map::Map& map() const { return *map_; }
  bool hasMap() const { return map_ != nullptr; }
  /// The inertial initialisation has been applied to the current map.
  bool inertialInitialized() const { return inertial_inits_ > 0; }
  /// Inertial (re-)initialisations applied to the current map.
  int inertialStages() const { return inertial_inits_; }
  int resets() const { return resets_; }
  /// Frames located again in their map after a tracking failure.
  int relocalizations() const { return relocalizations_; }
  /// Frames that became keyframes at the IMU-predicted pose (TrackerOptions::imu_reanchor).
  int reanchors() const { return reanchors_; }
  bool isMonocular() const { return cameras_.size() == 1; }
  /// The left camera's pose in the body frame.
  const SE3d& T_b_c0() const { return T_b_c0_; }

  /// Localization-only: from the next frame on, tracks against `map` (a loaded map file) without
  /// changing it: no keyframes, points, local BA or loop closing. Until a frame is located in it
  /// (locateInLoadedMap()), and again after a tracking failure, frames are kLocalizing; the
  /// reference keyframe follows the keyframe sharing most of the tracked points.
  /// inertial_stages: the map's inertial (re-)initialisations (0 = not gravity-aligned); the
  /// biases start from its newest keyframe's. With an IMU the prediction is the preintegration
  /// from the last frame (the map's keyframe states belong to another recording).
  void localizeIn(std::unique_ptr<map::Map> map, int inertial_stages);
  bool localizationOnly() const { return localization_only_; }
  /// The local mapper (its right-camera observations go into a saved map; read after the mapping
  /// jobs have run).
  const mapping::LocalMapper& mapper() const { return mapper_; }

  /// Hands the local-mapping jobs to `sink` (not owned, must outlive its use; nullptr = run them at
  /// once). With a sink, track() does not wait for local BA, so the pose of a new keyframe's frame
  /// is the tracked one, not the one local BA refines.
  void setMappingSink(MappingSink* sink) { mapping_sink_ = sink; }
  /// Calls `observer` (not owned, must outlive its use; nullptr = none) from the mapping jobs.
  void setKeyFrameObserver(KeyFrameObserver* observer) { observer_ = observer; }
  /// Where a map goes when tracking leaves it for a new one (not owned, must outlive its use;
  /// nullptr = maps are dropped): a map the observer has been told about (visual, or inertial
  /// once settled) with at least two keyframes, for loop closing to merge later (map/atlas.h).
  /// The maps of a run continue each other's ids either way.
  void setAtlas(map::Atlas* atlas) { atlas_ = atlas; }
  /// At the end of a run with a mapping sink, once its jobs and the observer's have run: waits for
  /// the global BA still being solved (and one requested meanwhile) and applies it.
  void finishGlobalBundleAdjust();

 private:
  struct LocalPoint {
    map::MapPointId id = map::kNoMapPoint;
    map::MapPoint point;  ///< Position and viewing geometry only (no descriptor, observations).
  };

  struct Prediction {
    SE3d T_w_b;
    bool from_imu = false;  ///< Rotation from gyroscope preintegration.
    /// After the inertial initialisation: predicted from the newest keyframe, with a pose prior.
    std::optional<InertialPrediction> inertial;
    /// A pose known to a few pixels (reference PnP): search this radius instead of
    /// projection.radius_px, without the wide retry.
    std::optional<double> search_radius_px;
  };
  /// The frame without the keypoints the moving-object test drops (result.moving, and the map
  /// points of moving objects culled); `kept` receives the indices of the kept keypoints.
  Frame removeMovingFeatures(const Frame& frame, const Prediction& prediction,
                             TrackingResult& result, std::vector<int>& kept);
  /// Keeps `frame` (all its keypoints) and the map points tracked by its kept keypoints for the
  /// next frame's moving-object test.
  void rememberFrame(const Frame& frame, const std::vector<int>& kept,
                     const std::vector<map::MapPointId>& tracked);
  std::optional<InertialPrediction> predictInertial(const Frame& frame) const;
  /// Where the velocity and biases of an inertial prediction come from: a keyframe and the IMU
  /// samples from it to the newest.
  struct PredictionStart {
    map::KeyFrameId keyframe = map::kNoKeyFrame;
    std::vector<sensors::ImuSample> samples;
  };
  /// The newest keyframe, from the reference back, whose inertial state an estimation has set
  /// (KeyFrame::inertial_estimated), with the samples since; the reference when none is within
  /// 32 keyframes. Call with the map's read lock held.
  PredictionStart predictionStart() const;
  /// The state inertial predictions start from: the reference keyframe's tracked pose (the
  /// newest), with the velocity and biases carried to it by the IMU from predictionStart().
  map::KeyFrame referenceInertialState() const;
  /// With IMU: runs the local mapper's inertial (re-)initialisation of the map when it is due.
  void initializeInertialIfDue(TrackingResult& result);
  /// After the inertial initialisation: the biases of the newest keyframe an estimation has set
  /// (predictionStart).
  void updateBiasFromMap();
  /// imu_usable false (an IMU gap in the frame's interval): the constant-velocity model only.
  Prediction predictPose(const Frame& frame, bool imu_usable) const;
  /// Adds the frame's IMU samples to the run since the keyframe; on a gap (imu_max_gap_s) restarts
  /// the run after it, reports a new gap in `result` and returns false (IMU not usable).
  bool collectImu(const Frame& frame, TrackingResult& result);
  SE3d predictWithImu(const imu::Preintegration& preintegration) const;
  std::optional<optim::PosePrior> rotationPrior(const Prediction& prediction) const;
  SE3d initialPose(const Frame& frame, const SE3d& predicted) const;
  SE3d gravityAlignedPose(const Frame& frame) const;
  bool inertialReady() const { return !isMonocular() || inertial_inits_ > 0; }
  void initializeMono(const Frame& frame, TrackingResult& result);
  bool buildMonoMap(const MonoInitialization& init, const Frame& frame, TrackingResult& result);
  /// The gyroscope's rotation from the initialiser's reference camera to this frame's (nullopt
  /// without IMU, reference or samples spanning both).
  std::optional<Eigen::Matrix3d> gyroRotationSinceReference(const Frame& frame) const;
  void setMotionFromInitialization(const SE3d& T_w_b0, TimeNs t0_ns, const SE3d& T_w_b1,
                                   TimeNs t1_ns);
  void normalizeMonoScale(map::KeyFrameId first);
  void initializeAt(const Frame& frame, const SE3d& T_w_b, TrackingResult& result);
  /// An empty map whose ids continue the current map's.
  std::unique_ptr<map::Map> newMap() const;
  /// Makes `next` the map: first no mapping job, global BA or observer thread may use the current
  /// one any more; it goes to the atlas when one is set and the map is worth keeping (setAtlas).
  void replaceMap(std::unique_ptr<map::Map> next);
  void startMap(const Frame& frame, const SE3d& T_w_b);
  /// A local-map search: the map point tracked by each keypoint of the frame (kNoMapPoint where
  /// none, all of them when tracking failed) and the points projected into the image.
  struct LocalMapTrack {
    std::vector<map::MapPointId> tracked;
    std::vector<map::MapPointId> visible;
  };
  /// Tracks the local map from the prediction, or from the reference keyframe's PnP pose when the
  /// motion is unknown or the prediction fails (reference_matching.h). The accepted search's
  /// points count as visible, and its tracked ones as found (map::MapPoint's culling ratio).
  std::vector<map::MapPointId> trackFrame(const Frame& frame, const Prediction& prediction,
                                          TrackingResult& result);
  std::vector<map::MapPointId> countObservations(LocalMapTrack track, bool found);
  /// The local-map search from the reference keyframe's PnP pose; nullopt (result untouched) when
  /// no pose is found or it has too few inliers.
  std::optional<LocalMapTrack> trackFromReference(const Frame& frame, TrackingResult& result);
  ReferenceView referenceView() const { return referenceView(reference_); }
  ReferenceView referenceView(map::KeyFrameId id) const;
  /// Localization-only, frame not located yet: the best PnP pose over the loaded map's keyframes
  /// (reference_matching.h against each keyframe's points, most inliers), then the local-map
  /// search from it (tracker_localization.cc). Sets result.state kTracking when located, else
  /// kLocalizing.
  std::vector<map::MapPointId> locateInLoadedMap(const Frame& frame, TrackingResult& result);
  /// The best PnP pose of the frame against the candidates' points (most inliers), then the
  /// local-map search from it with that keyframe as the reference; nullopt (result and reference
  /// untouched) when no candidate gives a pose with reference_matching.min_inliers inliers.
  std::optional<LocalMapTrack> locateAmong(const Frame& frame,
                                           const std::vector<map::KeyFrameId>& candidates,
                                           TrackingResult& result);
  /// After a failed search within relocalization_s of the failure's first frame: the frame located
  /// among the keyframes place recognition proposes (KeyFrameObserver::recognizePlace) and those
  /// nearest to the prediction (relocalization_candidates of each); on success result is the
  /// located frame's (kTracking, relocalized) and the tracked points are returned.
  std::optional<std::vector<map::MapPointId>> relocalize(const Frame& frame,
                                                         const Prediction& prediction,
                                                         TrackingResult& result);
  /// The keyframes nearest to T_w_b's position, nearest first, at most `count`.
  std::vector<map::KeyFrameId> keyFramesNear(const SE3d& T_w_b, int count) const;
  /// Within relocalization_s of the first frame of the current failure (ORB-SLAM3's
  /// time-since-lost: a stream that resumes after a gap still gets its window).
  /// Always false with relocalization_s 0 (a new map at the first failure).
  bool withinRelocalizationWindow(const Frame& frame) const {
    return options_.relocalization_s > 0.0 &&
           frame.t_ns - t_failed_ns_ <= secondsToNs(options_.relocalization_s);
  }
  /// After a relocalisation: the motion model restarts at the located pose (the poses before it
  /// were predictions); with the IMU prediction's velocity when there is one.
  void restartMotionAt(const SE3d& T_w_b, TimeNs t_ns, const Prediction& prediction);
  /// Localization-only: the keyframe observing most of the tracked points becomes the reference.
  void followTrackedKeyFrame(const std::vector<map::MapPointId>& tracked);
  LocalMapTrack trackLocalMap(const Frame& frame, const Prediction& prediction,
                              TrackingResult& result);
  void addKeyFrameAndMap(const Frame& frame, const std::vector<map::MapPointId>& tracked,
                         const Prediction& prediction, TrackingResult& result);
  /// The points of the reference keyframe and its best covisible keyframes.
  std::set<map::MapPointId> localPointIds() const;
  /// Sets result.reference to the reference keyframe with its current pose (read-locked map).
  void noteReference(TrackingResult& result) const;
  std::vector<LocalPoint> localPoints() const;
  /// Culls the local map's points on the instances the moving-object test found moving
  /// (dynamic.cull_points_by_instance); returns how many.
  int cullPointsOnMovingInstances(const dynamic::MovingObjectReport& report);
  /// Matches the points projected from T_w_b within options.radius_px (retried at
  /// wide_radius_px when too few, if `allow_wide`); the ids of the points that project into the
  /// image are appended to `visible_ids` when given.
  std::vector<features::Match> matchLocalPoints(const Frame& frame,
                                                const std::vector<LocalPoint>& points,
                                                const SE3d& T_w_b,
                                                const features::ProjectionMatchOptions& options,
                                                bool allow_wide,
                                                std::vector<map::MapPointId>* visible_ids);
  /// The pose and inliers of the refine_radius_px search from `pose` (see TrackerOptions), or
  /// nullopt when it finds fewer inliers than `pose` has.
  std::optional<std::pair<optim::PoseOptimizationResult, std::vector<features::Match>>>
  refineByReprojection(const Frame& frame, const std::vector<LocalPoint>& points,
                       const Prediction& prediction, const optim::PoseOptimizationResult& pose,
                       int inliers);
  std::vector<optim::PoseObservation> poseObservations(
      const Frame& frame, const std::vector<LocalPoint>& points,
      const std::vector<features::Match>& matches) const;
  bool needKeyFrame(const Frame& frame, int inliers) const;
  /// Whether a tracking failure at `frame` may be bridged by the IMU prediction (kRecentlyLost).
  bool canBridgeWithImu(const Frame& frame, const Prediction& prediction) const;
  /// Whether a frame that could not be tracked may become a keyframe at its IMU-predicted pose
  /// (TrackerOptions::imu_reanchor).
  bool canReanchorWithImu(const Frame& frame, const Prediction& prediction) const;
  bool weakTracking(int inliers) const { return inliers < options_.keyframe_weak_inliers; }
  /// Monocular with a mapping thread: whether a wanted keyframe may be inserted now (waits for a
  /// busy mapper first; see mono_wait_for_mapping for when it is refused instead).
  bool mappingAcceptsKeyFrame(const Frame& frame, int inliers);
  int referenceTrackedPoints() const;
  /// Moves the tracker's last pose and velocity (and *pose, when given) by the map corrections
  /// recorded since the last call (the loop closer's); returns their composition.
  map::KeyFrameCorrection followMapCorrections(SE3d* pose = nullptr);
  /// Whether the keyframe observer may see this map's keyframes (see KeyFrameObserver).
  bool mapSettled() const;
  /// Inserts the keyframe at T_w_b, first moved by any map correction not followed yet.
  map::KeyFrameId insertKeyFrame(const Frame& frame, SE3d& T_w_b,
                                 const std::vector<map::MapPointId>& tracked,
                                 const std::optional<Eigen::Vector3d>& v_w = std::nullopt);
  std::vector<map::MapPointId> createStereoPoints(const Frame& frame, const SE3d& T_w_b,
                                                  map::KeyFrameId keyframe,
                                                  const std::vector<map::MapPointId>& tracked);
  void updateMotion(const SE3d& T_w_b, TimeNs t_ns);
  void runMapping(std::function<void()> job);
  /// Returns once the mapping jobs submitted so far have run (at once without a sink).
  void waitForMapping();
  /// The query keypoint of a map point in projection matching.
  features::Keypoint queryKeypoint(map::MapPointId id) const;

  TrackerOptions options_;
  PyramidInfo pyramid_;
  CameraModel camera0_;
  SE3d T_b_c0_;
  optim::PoseOptimizer pose_optimizer_;
  std::vector<optim::ReprojectionCamera> cameras_;
  std::optional<sensors::ImuCalibration> imu_;
  imu::Bias bias_;
  ImuSampleBuffer imu_since_keyframe_;  ///< Samples since the newest keyframe.
  TimeNs last_imu_gap_end_ns_ = 0;      ///< End of the last IMU gap reported.
  double baseline_m_ = 0.0;
  std::unique_ptr<map::Map> map_;
  mapping::LocalMapper mapper_;  ///< Used only by mapping jobs (see MappingSink).
  MappingSink* mapping_sink_ = nullptr;
  KeyFrameObserver* observer_ = nullptr;
  map::Atlas* atlas_ = nullptr;
  int corrections_followed_ = 0;  ///< Of the current map's recorded corrections.

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
  TimeNs t_tracked_ns_ = 0;  ///< The last frame tracked against the map.
  bool failing_ = false;     ///< The last frame on the map was not tracked.
  TimeNs t_failed_ns_ = 0;   ///< The first frame of the current failure.
  int resets_ = 0;
  int relocalizations_ = 0;
  int reanchors_ = 0;

  std::optional<MonoInitializer> mono_initializer_;  ///< Monocular rigs only.
  dynamic::MovingObjectDetector moving_detector_;
  std::optional<Frame> previous_frame_;  ///< The last frame, all keypoints (dynamic.mode on).
  std::vector<map::MapPointId> previous_tracked_;  ///< Its keypoints' map points, same indexing.
  int inertial_inits_ = 0;          ///< Inertial (re-)initialisations of the current map.
  bool localization_only_ = false;  ///< Tracking a loaded map without changing it.
  bool located_ = false;            ///< Localization-only: the last frame was tracked on it.
};

}  // namespace superdyna::tracking

#pragma once
// The SLAM system facade: feeds FrameBundles through the front end (features, stereo), tracking and
// local mapping and records the body trajectory of every frame, the keyframe trajectory and
// per-stage timings.
//
// Two pipelines:
// - deterministic: all stages run one after the other in the caller's thread, so the same input
//   gives a bit-identical trajectory;
// - concurrent (ORB-SLAM style): local mapping runs in its own thread (MappingWorker) fed by a
//   bounded job queue, so tracking does not wait for local BA; in run() the front end also runs in
//   its own thread, up to `frame_queue` frames ahead of tracking, and loop detection in its own
//   (LoopStage). Tracking stays in the caller's thread. Results vary slightly from run to run
//   (local BA ends at different frames).
// The map is mutex-protected; the LocalMapper is only used by the mapping thread (MappingSink).
//
// Monocular frames without a pose (map initialisation) are not recorded; when the tracker rescales
// / rotates the current map (mono-inertial inertial initialisation), the poses recorded on it
// follow.

#include <cstddef>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "superdyna/core/task_thread.h"
#include "superdyna/core/trajectory.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/loop/loop_closer.h"
#include "superdyna/map/map_file.h"
#include "superdyna/mapping/local_mapper.h"
#include "superdyna/semantics/segmenter.h"
#include "superdyna/system/loop_stage.h"
#include "superdyna/system/mapping_worker.h"
#include "superdyna/tracking/front_end.h"
#include "superdyna/tracking/tracker.h"

namespace superdyna::system {

enum class SensorMode { kStereo, kStereoInertial, kMono, kMonoInertial };

/// "stereo" | "stereo-inertial" | "mono" | "mono-inertial"; others throw OptionError.
SensorMode parseSensorMode(const std::string& name);
std::string toString(SensorMode mode);
bool usesImu(SensorMode mode);
/// Mono modes use cam0 only (a given cam1 is ignored).
bool isMonocular(SensorMode mode);

struct SystemOptions {
  SensorMode mode = SensorMode::kStereo;
  tracking::FrontEndOptions front_end;
  tracking::TrackerOptions tracker;
  mapping::LocalMapperOptions mapping;
  /// Instance segmentation (section `semantics`); the System runs the segmenter it is given.
  semantics::SegmenterOptions semantics;
  /// Loop closing (section `loop`): SE(3) loops in stereo and inertial maps (an inertial map's
  /// keyframes reach it once its inertial stages have run), Sim(3) loops in visual mono maps.
  loop::LoopClosingOptions loop;
  bool deterministic = true;  ///< Sequential pipeline; false = concurrent (see above).
  int frame_queue = 2;        ///< Concurrent: frames the front end may build ahead, >= 1.
  int mapping_queue = 16;     ///< Concurrent: mapping jobs (2 per keyframe) that may wait, >= 1.
  void validate() const;
  bool operator==(const SystemOptions&) const = default;
};

/// Copies the one matching option, features.class_wise_matching, to every matcher: stereo,
/// map-to-frame projection, reference keyframe, monocular initialisation and keyframe-to-keyframe
/// triangulation (their same_class_only). The System applies it to its options.
void applyClassWiseMatching(SystemOptions& options);

/// Reads a YAML options file (sections `features`, `orb`, `stereo`, `projection`, `pose`,
/// `tracker`, `dynamic`, `mono_init`, `mapping`, `semantics`, `loop`, `pipeline`) over `defaults`;
/// an unknown section or key is an InputError naming file and key.
SystemOptions loadSystemOptions(const std::filesystem::path& file, SystemOptions defaults = {});

/// The options as an options file that loadSystemOptions reads back to the same values: every key
/// of every section (one table serves both), numbers in their shortest exact decimal form. The
/// mode and the pipeline, which come from the command line, are named in a comment.
std::string formatSystemOptions(const SystemOptions& options);

/// Writes formatSystemOptions(options) to `file`; InputError naming the file when it cannot.
void writeSystemOptions(const std::filesystem::path& file, const SystemOptions& options);

/// CPU time each thread of the pipeline used [ms] (CPU, not wall-clock, time: meaningful on a
/// loaded machine too). In the deterministic pipeline everything runs in the caller's thread.
struct ThreadBusyTimes {
  double front_end_ms = 0.0;  ///< Reading the dataset (in run()), extraction, stereo.
  /// The front end's helper thread extracting right images (FrontEndOptions::parallel_extraction).
  double extraction_helper_ms = 0.0;
  /// The front end's segmentation thread (segmenting while the features are extracted).
  double segmentation_ms = 0.0;
  double tracking_ms = 0.0;  ///< Tracking and keyframe insertion (plus local BA if sequential).
  double mapping_ms = 0.0;   ///< The mapping thread (concurrent only).
  double loop_ms = 0.0;      ///< The loop-closing thread (concurrent only).
};

/// Match counts summed over the processed frames. Cross-class matches pair keypoints (or a map
/// point and a keypoint) of different semantic classes; class-wise matching makes them 0.
struct MatchCounts {
  long stereo = 0;              ///< Left keypoints with a stereo partner.
  long stereo_cross_class = 0;  ///< ... whose partner has another class_id.
  long map = 0;                 ///< Map-to-frame matches (before pose-outlier rejection).
  long map_cross_class = 0;     ///< ... between a map point and a keypoint of other classes.
};

/// What the moving-object test removed, summed over the processed frames.
struct MovingObjectCounts {
  long keypoints = 0;          ///< Left keypoints of the frames (before the test).
  long dropped = 0;            ///< ... dropped by the test (objects and the geometric test).
  long geometric_dropped = 0;  ///< ... of them background keypoints of the geometric test.
  long moving = 0;             ///< Object-frames decided moving.
  long static_objects = 0;     ///< Object-frames decided static.
  long unverified = 0;         ///< Object-frames left unverified.
};

/// Sums of the per-stage times over the processed frames [ms], and match counts.
struct TimingSummary {
  std::size_t frames = 0;
  std::size_t keyframes = 0;
  /// Per stage. local_ba_ms: keyframe insertion and local mapping, wherever they ran.
  tracking::StageTimes total;
  ThreadBusyTimes busy;
  double wall_s = 0.0;      ///< Wall-clock time of process() / run() calls, to the end of mapping.
  double segment_ms = 0.0;  ///< Segmentation (both images) in the front end, summed.
  std::size_t segmented_frames = 0;   ///< Frames whose images the segmenter saw.
  std::size_t propagated_frames = 0;  ///< Frames with masks propagated (every_n_frames > 1).
  double propagate_ms = 0.0;          ///< Mask propagation, summed.
  MatchCounts matches;
  MovingObjectCounts moving_objects;
  double meanMs(double total_ms) const { return frames > 0 ? total_ms / frames : 0.0; }
  double framesPerSecond() const { return wall_s > 0.0 ? frames / wall_s : 0.0; }
};

/// Called in the tracking thread after each frame.
using FrameCallback = std::function<void(const tracking::TrackingResult&)>;
/// Called in the front-end thread after each frame is built: the bundle with the masks its
/// keypoints were labelled with, and the frame.
using FrontEndCallback = std::function<void(const sensors::FrameBundle&, const tracking::Frame&)>;

class System {
 public:
  /// With a segmenter (semantics::makeSegmenter(options.semantics, dataset)), every frame's left
  /// image (and the right one, SegmenterOptions::right_labels) is segmented and its keypoints
  /// labelled with those masks instead of the bundle's.
  System(const SystemOptions& options, const sensors::CameraCalibration& cam0,
         const std::optional<sensors::CameraCalibration>& cam1,
         const std::optional<sensors::ImuCalibration>& imu,
         std::unique_ptr<semantics::Segmenter> segmenter = nullptr);

  System(const System&) = delete;
  System& operator=(const System&) = delete;
  /// Stops the mapping thread (dropping its queued jobs) without rethrowing its errors.
  ~System();

  /// Front end and tracking of one frame in the caller's thread. Concurrent pipeline: local mapping
  /// of a new keyframe is queued for the mapping thread (call finish() after the last frame).
  tracking::TrackingResult process(const sensors::FrameBundle& bundle);

  /// Processes every remaining frame of `source`, calling on_frame after each one, then finish().
  /// Concurrent pipeline: the front end reads and prepares frames in its own thread. An error in
  /// any thread stops all of them and is rethrown here.
  void run(io::DatasetSource& source, const FrameCallback& on_frame = {});

  /// Waits for local mapping to process every queued keyframe and stops the mapping thread;
  /// rethrows its error, if any. Idempotent; processing may continue afterwards.
  void finish();

  /// Called for every frame the front end builds (set before process() / run()).
  void setFrontEndCallback(FrontEndCallback callback) { front_end_callback_ = std::move(callback); }

  const SystemOptions& options() const { return options_; }
  /// Every recorded frame's pose as it is now: a frame tracked on the current map follows the
  /// later corrections of the keyframe it was tracked against (its pose relative to that keyframe
  /// is kept; an erased keyframe is resolved through its anchor, map::Map::resolvedKeyFramePose),
  /// as ORB-SLAM reports its frames, and so do the frames of maps left at resets and merged into
  /// the current one since (keyframe ids are unique over the run's maps); frames of maps left and
  /// not merged, and frames tracked on no map, keep their poses as tracked. Call after finish()
  /// for the final poses.
  Trajectory trajectory() const;
  /// Every recorded frame's pose as the tracker reported it at that frame (causal: with the loop
  /// corrections known by then, no later ones, apart from changes of the world frame such as the
  /// inertial initialisation's).
  Trajectory onlineTrajectory() const;
  /// Keyframes in time order: those of the current map (merged maps included) with their latest
  /// (local-BA refined) poses, those of maps left at resets and not merged with their poses at
  /// insertion. Call after finish() for the final poses.
  Trajectory keyFrameTrajectory() const;
  const TimingSummary& timings() const { return timings_; }
  std::size_t lostFrames() const { return lost_frames_; }
  /// Frames tracked from the reference keyframe's PnP pose (tracking/reference_matching.h).
  std::size_t referenceTrackedFrames() const { return reference_frames_; }
  /// Monocular: frames spent initialising a map (no pose estimate; not in the trajectory).
  std::size_t initializingFrames() const { return initializing_frames_; }
  int resets() const { return tracker_.resets(); }
  /// Frames located again in their map after a tracking failure (tracker.relocalization_s).
  int relocalizations() const { return tracker_.relocalizations(); }
  /// Frames that became keyframes at the IMU-predicted pose (tracker.imu_reanchor).
  int reanchors() const { return tracker_.reanchors(); }
  std::size_t numKeyFrames() const;
  std::size_t numMapPoints() const;
  /// Points of the current map observed by keypoints of different classes (map::Map).
  std::size_t numCrossClassMapPoints() const;
  /// The current map's points (not culled): world position and semantic class, for viewers.
  std::vector<std::pair<Eigen::Vector3d, int>> mapPointPositions() const;
  /// Points of the current map by the instance id of the object they lie on (0 = background).
  std::map<int, std::size_t> mapPointsPerInstance() const;
  /// The inertial initialisation has been applied to the current map.
  bool inertialInitialized() const { return tracker_.inertialInitialized(); }
  /// Inertial initialisation stages applied to the current map (0: none yet, 1: initialised, 2
  /// and 3: refined; mapping::LocalMapperOptions refine_first_s, refine_second_s). Read it from
  /// the tracking thread (run()'s on_frame).
  int inertialStages() const { return tracker_.inertialStages(); }
  /// Loop closing over the run so far (all zero when off); call after finish() for the final one.
  LoopSummary loopSummary() const;

  /// What a map file must have been made with to be loaded here: feature type, sensor mode, the
  /// rig's calibrations (the descriptor type is left kNone: the feature type implies it).
  const map::MapIdentity& mapIdentity() const { return identity_; }
  /// The current map as a map file (map/map_file.h): keyframes, points, the mapper's right-camera
  /// observations and the inertial state; nullopt when there is no map. Call after finish().
  std::optional<map::MapFile> mapFile() const;
  /// Localization-only: every following frame is tracked against the file's map without changing
  /// it (tracking::Tracker::localizeIn; loop closing and mapping stay idle). InputError naming
  /// `name` and the difference when the map was made with other features, mode or rig.
  void localizeIn(const map::MapFile& file, const std::filesystem::path& name);
  /// Localization-only: frames that could not be located in the loaded map (no pose estimate;
  /// not in the trajectory).
  std::size_t localizingFrames() const { return localizing_frames_; }

 private:
  tracking::TrackingResult track(const tracking::Frame& frame);
  /// Adds the frame's keypoints and what the moving-object test removed of them to the counts.
  void countMovingObjects(const tracking::Frame& frame, const dynamic::MovingObjectReport& report);
  /// The front end's frame of a bundle, its keypoints labelled with the segmenter's masks when
  /// there is one. Runs in the front-end thread.
  tracking::Frame buildFrame(const sensors::FrameBundle& bundle);
  /// The front end's frame of a bundle labelled with masks: the segmenter's, computed beside the
  /// feature extraction (or started ahead, segmentAhead), on every N-th frame
  /// (SegmenterOptions::every_n_frames), else propagated from the frame before. `masks` receives
  /// them.
  tracking::Frame buildSegmentedFrame(const sensors::FrameBundle& bundle,
                                      std::optional<sensors::InstanceMasks>& masks);
  /// Concurrent pipeline: starts segmenting `next`, the bundle after the one about to be built,
  /// when it will be segmented and the segmentation thread is free, so that the network runs
  /// beside the building of the frame before it as well. The masks are the same as when started
  /// with the frame's own build; only the waiting changes.
  void segmentAhead(const sensors::FrameBundle& next);
  /// Whether the frame built after `built` earlier ones is segmented rather than propagated.
  bool segmentsFrame(std::size_t built) const;
  /// Starts segmenting `bundle` (a shallow copy is kept) on the segmentation thread.
  void startSegmentation(const sensors::FrameBundle& bundle);
  /// Waits for the segmentation started by startSegmentation and returns its masks.
  sensors::InstanceMasks finishSegmentation();
  /// Waits for a segmentation started ahead for a frame that will not be built (the run ended).
  void discardSegmentation();
  /// The segmenter's masks of both images of a bundle.
  sensors::InstanceMasks segment(const sensors::FrameBundle& bundle);
  /// The masks of a frame not segmented, propagated from the frame before.
  sensors::InstanceMasks propagate(const features::FeatureSet& left);
  /// Copies the front end's segmentation counters and helper threads' CPU times to timings_.
  void collectFrontEndTimes();
  /// Appends the frame to the trajectory (initialising mono frames are counted, not recorded) and
  /// applies a change of the world of the current map to the poses recorded on it.
  void record(TimeNs t_ns, const tracking::TrackingResult& result);
  void runSequentially(io::DatasetSource& source, const FrameCallback& on_frame);
  void runConcurrently(io::DatasetSource& source, const FrameCallback& on_frame);

  /// A keyframe as inserted, with its id (unique over the run's maps).
  struct InsertedKeyFrame {
    StampedPose pose;
    map::KeyFrameId id = map::kNoKeyFrame;
  };

  SystemOptions options_;
  tracking::FrontEnd front_end_;
  std::unique_ptr<semantics::Segmenter> segmenter_;
  FrontEndCallback front_end_callback_;
  double segment_ms_ = 0.0;  ///< Segmentation thread's time per job, summed; copied to timings_.
  std::size_t segmented_frames_ = 0, propagated_frames_ = 0;  ///< Copied to timings_.
  double propagate_ms_ = 0.0;                                 ///< Copied to timings_.
  /// The bundle being segmented on segment_thread_ (a shallow copy: the job reads it) and the
  /// masks the job writes; segmenting_ while a job has been started and not waited for. Declared
  /// before segment_thread_, which waits for its job when destroyed.
  sensors::FrameBundle segmenting_bundle_;
  std::optional<sensors::InstanceMasks> segmented_masks_;
  bool segmenting_ = false;
  std::unique_ptr<TaskThread> segment_thread_;  ///< Segments while the front end extracts.
  semantics::MaskPropagator propagator_;        ///< Masks of the frames not segmented.
  /// The maps tracking left, for loop closing to merge (map/atlas.h); declared before the
  /// tracker and the loop stage that use it.
  map::Atlas atlas_;
  /// Declared before mapping_ (destroyed after it): the mapping jobs call it.
  std::unique_ptr<LoopStage> loop_;
  tracking::Tracker tracker_;
  /// Declared after tracker_ (destroyed first): its jobs use the tracker.
  std::unique_ptr<MappingWorker> mapping_;
  /// A recorded frame: its pose as tracked, and its left camera's pose in the camera of the
  /// keyframe it was tracked against (reference kNoKeyFrame: none).
  struct FrameRecord {
    StampedPose online;
    map::KeyFrameId reference = map::kNoKeyFrame;
    SE3d T_cr_c;
  };
  std::vector<FrameRecord> frames_;
  std::vector<InsertedKeyFrame> keyframes_;
  TimingSummary timings_;
  double mapping_wall_ms_ = 0.0;  ///< Mapping thread's job time already in timings_.
  std::size_t lost_frames_ = 0;
  std::size_t reference_frames_ = 0;
  std::size_t initializing_frames_ = 0;
  std::size_t localizing_frames_ = 0;
  map::MapIdentity identity_;
  /// Localization-only: the loaded map's right-camera observations (saved with it again).
  std::map<map::KeyFrameId, map::RightKeypoints> loaded_right_;
  std::size_t map_start_ = 0;  ///< First frames_ entry estimated on the current map.
};

}  // namespace superdyna::system

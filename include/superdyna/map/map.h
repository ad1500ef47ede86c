#pragma once
// The map: owns keyframes and map points, keeps the observations consistent in both directions
// (KeyFrame::map_points <-> MapPoint::observations) and maintains the covisibility graph.
//
// Ownership: other code holds ids (KeyFrameId, MapPointId), never pointers into the map. Ids come
// from counters of this Map (no global state), start at 0 (or where the map before left off, so
// that the maps of a run never share an id: atlas.h) and are never reused.
//
// Covisibility: two keyframes are covisible when they observe a common map point; the weight of
// the edge is the number of such points. The graph is updated incrementally by every observation
// change (add, erase, replace, erasing keyframes or points), so it always equals the graph one
// would rebuild from the observations (consistencyError() checks that).
//
// Thread safety, single calls: one std::mutex per Map guards all its state. Every public member
// function locks it for its own duration, so single calls are atomic and the map never exposes a
// half-updated observation. Accessors return copies (or run a read-only callback under the lock,
// see readKeyFrame()).
//
// Thread safety, map updates: a sequence of calls is not atomic by itself. A change made in several
// calls (a bundle adjustment's write-back and outlier removal, point culling, keyframe culling,
// triangulated points, the tracker's insertion of a keyframe and its points) is one map update: its
// thread holds updateLock() (exclusive) over all of its calls. A reader that needs several calls to
// agree (the tracker's frame: prediction from the reference keyframe, local points, projection
// matching, keyframe decision) holds readLock() (shared) over them; it then sees each update
// entirely or not at all (ORB-SLAM3's map-update mutex). The rules:
// - Neither lock is recursive: a thread holding one takes neither again (the deterministic pipeline
//   runs the mapper's updates in the tracker's thread, so the tracker releases its read lock
//   first).
// - A thread holding either lock never waits for another thread that may take updateLock(): the
//   tracker releases its read lock before it submits a job to the mapping thread or waits for it
//   (MappingSink::submit, waitIdle, discardPending).
// - Under readLock() a thread may still make single-call changes that need no transaction (the
//   tracker's visible/found counters); the per-call mutex keeps those atomic.
// - Calls made without either lock stay atomic one by one, as before; code that runs while no
//   other thread uses the map (the tracker's map initialisation, the inertial initialisation with
//   the mapping thread idle) needs no lock.
// The per-call mutex is always taken inside the update lock, never the other way round, so the
// callbacks of readKeyFrame() and readMapPoint() must not take either lock.

#include <Eigen/Core>
#include <cstddef>
#include <map>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <optional>
#include <shared_mutex>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/map/keyframe.h"
#include "superdyna/map/map_point.h"

namespace superdyna::map {

struct MapOptions {
  /// Pose of each camera of the rig in the body frame, indexed by KeyFrameKeypoint::camera.
  /// Default: a single camera at the body origin.
  std::vector<SE3d> T_b_c = {SE3d()};
  /// Scale between consecutive pyramid levels of the feature extractor. Default 1.2 (ORB).
  double scale_factor = 1.2;
  /// Number of pyramid levels of the feature extractor. Default 8 (ORB).
  int num_levels = 8;
  /// IMU samples a keyframe keeps from its predecessor at most: a link that culling lengthened
  /// beyond it is thinned (thinImuSamples), so that a map of bounded size holds bounded IMU data
  /// however long the run (without it every sample since the first keyframe stays: 0.67 MB per
  /// minute at 200 Hz). 1024 leaves links up to 5 s at 200 Hz untouched (the inertial window's
  /// gaps are at most mapping.cull_max_gap_inertial_s, 3 s); only the long links of keyframes far
  /// behind the newest (mapping.cull_max_gap_old_s) are thinned.
  std::size_t max_imu_samples_per_link = 1024;

  /// Throws OptionError when there is no camera, num_levels < 1, scale_factor < 1 (<= 1
  /// with more than one level) or max_imu_samples_per_link < 16.
  void validate() const;
};

/// A covisible keyframe and the number of map points it shares.
struct CovisibleKeyFrame {
  KeyFrameId id = kNoKeyFrame;
  int weight = 0;

  bool operator==(const CovisibleKeyFrame&) const = default;
};

/// The samples of `earlier` followed by those of `later` newer than the last of `earlier`: the
/// IMU run across two consecutive gaps (both bracket the time they share).
std::vector<sensors::ImuSample> mergeImuSamples(const std::vector<sensors::ImuSample>& earlier,
                                                const std::vector<sensors::ImuSample>& later);

/// At most `max_samples` (>= 3) samples spanning the same time as `samples` (increasing times):
/// the first and the last kept as they are (they bracket the link's keyframes), those between
/// replaced by their means over max_samples - 2 bins of equal duration (empty bins give none).
/// The integral of each signal over the link, which is what preintegration needs, stays up to
/// the interpolation between coarser samples. Unchanged when short enough.
std::vector<sensors::ImuSample> thinImuSamples(std::vector<sensors::ImuSample> samples,
                                               std::size_t max_samples);

/// How a loop correction moves one keyframe and everything placed relative to it. Rigid
/// (scale 1): T_new = C * T_old. With a scale (monocular maps, Sim(3)): the similarity (scale, C)
/// applied to the pose, rotation C.q * q_old and position scale * (C.q * t_old) + C.t; points
/// p_new = scale * (C.q * p_old) + C.t. With scale 1 both are exactly SE3d's products.
struct KeyFrameCorrection {
  TimeNs t_ns = 0;  ///< The keyframe's time.
  SE3d C;
  double scale = 1.0;

  SE3d apply(const SE3d& T) const { return SE3d(C.q * T.q, scale * (C.q * T.t) + C.t); }
  Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return scale * (C.q * p) + C.t; }
  /// This correction applied after `first`: apply(first.apply(x)) for every x.
  KeyFrameCorrection after(const KeyFrameCorrection& first) const {
    return {t_ns, apply(first.C), scale * first.scale};
  }
};

/// A correction of the map's keyframes that does not move the world as a whole (a loop closure's
/// pose graph): each listed keyframe moved by its correction. Poses held outside the map (the
/// tracker's last frame, the recorded frame trajectory) follow it with the correction of the
/// keyframe nearest before them in time (correctionAt()).
struct MapCorrection {
  /// Every corrected keyframe's correction, by increasing time.
  std::vector<KeyFrameCorrection> keyframes;

  /// The correction of the keyframe with the latest time <= t_ns (the first one before all;
  /// identity when empty).
  KeyFrameCorrection correctionAt(TimeNs t_ns) const;
};

/// Everything that makes up a map, ids included: what a map file stores (map_file.h). The
/// covisibility graph and the point descriptors' owners follow from the observations.
struct MapContents {
  /// By increasing id; map_points hold the observations (one slot per keypoint).
  std::vector<KeyFrame> keyframes;
  /// Points that are not bad, by increasing id; observations agree with the keyframes' slots.
  std::vector<MapPoint> points;
  KeyFrameId next_keyframe_id = 0;  ///< The id the next keyframe added gets.
  MapPointId next_point_id = 0;     ///< ... and the next point.
};

class Map {
 public:
  /// Validates the options (OptionError).
  explicit Map(MapOptions options = {});
  /// A map whose ids start at the given ones instead of 0: the maps of one run continue each
  /// other's counters (next ids of the map before), so that ids stay unique across an atlas
  /// (atlas.h) and two of its maps can become one (absorb()).
  Map(MapOptions options, KeyFrameId first_keyframe_id, MapPointId first_point_id);
  Map(const Map&) = delete;
  Map& operator=(const Map&) = delete;

  const MapOptions& options() const { return options_; }

  /// A map holding `contents` with their ids (a loaded map file). Throws std::invalid_argument
  /// describing the first inconsistency: duplicate or out-of-range ids, a predecessor that is not
  /// in the map, descriptors or slots that do not match the keypoints, an observation of an
  /// unknown keyframe, an invalid keypoint or another point's slot, slots without the point's
  /// observation.
  static std::unique_ptr<Map> fromContents(MapOptions options, MapContents contents);
  /// The keyframes and points (not bad) by increasing id, and the id counters (under the lock).
  /// Erased keyframes' anchors and the correction log are not part of it.
  MapContents contents() const;

  // ---- Map updates (see "Thread safety" above) --------------------------------------------------

  using UpdateLock = std::unique_lock<std::shared_mutex>;
  using ReadLock = std::shared_lock<std::shared_mutex>;
  /// Exclusive: held over all the calls of one multi-call map update. Waits for readers to leave.
  [[nodiscard]] UpdateLock updateLock() { return UpdateLock(update_mutex_); }
  /// Shared: held over reads that must see each update entirely or not at all.
  [[nodiscard]] ReadLock readLock() const { return ReadLock(update_mutex_); }

  // ---- Structure -------------------------------------------------------------------------------

  /// Adds a keyframe and returns its new id (keyframe.id is overwritten; keyframe.previous becomes
  /// the newest keyframe of the map, kNoKeyFrame when empty). map_points may be empty
  /// (no associations) or hold one entry per keypoint: each id of a map point in the map (and not
  /// bad) becomes an observation; other ids are cleared to kNoMapPoint. Throws
  /// std::invalid_argument when descriptors has rows but not one per keypoint, map_points has the
  /// wrong size, or a keypoint names a camera outside options().T_b_c.
  KeyFrameId addKeyFrame(KeyFrame keyframe);

  /// Adds a map point and returns its new id (point.id is overwritten). Observations are added with
  /// addObservation(); throws std::invalid_argument when point.observations is not empty.
  MapPointId addMapPoint(MapPoint point);

  /// Records that keypoint `keypoint_index` of the keyframe observes the point, on both sides, and
  /// updates the covisibility weights. A point is observed at most once per keyframe and a keypoint
  /// observes at most one point: an observation of the point in the keyframe at another index,
  /// and another point at this keypoint, are replaced. Returns false (and changes nothing) when
  /// either id is unknown, the point is bad or the index is out of range.
  bool addObservation(MapPointId point_id, KeyFrameId keyframe_id, int keypoint_index);

  /// Removes the observation of the point in the keyframe on both sides; false when there is none.
  bool eraseObservation(MapPointId point_id, KeyFrameId keyframe_id);

  /// Erases a keyframe with all its observations and covisibility edges. Returns the ids of the
  /// points that were left without any observation (the caller decides whether to cull them), or
  /// nullopt when the keyframe is unknown. The temporal chain stays connected: the successor takes
  /// the erased keyframe's predecessor and the concatenation of both IMU sample runs
  /// (mergeImuSamples, thinned to MapOptions::max_imu_samples_per_link); without a predecessor, or
  /// when its own run does not reach back to the erased keyframe (restarted after an IMU gap), its
  /// samples are cleared.
  std::optional<std::vector<MapPointId>> eraseKeyFrame(KeyFrameId id);

  /// Erases a map point with all its observations; false when unknown.
  bool eraseMapPoint(MapPointId id);

  /// Culls a point in two steps: removes its observations and flags it bad, but keeps it so that
  /// ids held elsewhere still resolve (and tell it was culled) until eraseBadMapPoints().
  /// False when unknown.
  bool setMapPointBad(MapPointId id);
  /// Erases all bad points; returns how many.
  int eraseBadMapPoints();

  /// Fuses point `old_id` into `new_id`: every keyframe observing the old point and not the new one
  /// observes the new one at the same keypoint; the visible/found counters are added; the old
  /// point is erased. False when the ids are equal or unknown, or the new point is bad.
  bool replaceMapPoint(MapPointId old_id, MapPointId new_id);

  /// Moves every keyframe, point, covisibility edge and erased keyframe's anchor of `other` into
  /// this map (map merging: `other` already transformed into this map's frame, see
  /// transformWorld()), leaving `other` empty. The two maps share no observation, so they are
  /// linked only by what the caller adds afterwards (fused points). The id counters become the
  /// larger of both; other's correction log is dropped (poses recorded on it resolve through its
  /// keyframes, which keep their ids). Throws std::invalid_argument, changing nothing, when the
  /// maps share an id, have other rigs or `other` is this map. No thread may use `other`.
  void absorb(Map& other);

  // ---- State that does not change the structure -------------------------------------------------

  bool setKeyFramePose(KeyFrameId id, const SE3d& T_w_b);
  /// An estimate of velocity v_w [m/s], gyroscope bias bg [rad/s] and accelerometer bias ba
  /// [m/s^2]; marks the keyframe's inertial state estimated (KeyFrame::inertial_estimated).
  bool setKeyFrameInertialState(KeyFrameId id, const Eigen::Vector3d& v_w,
                                const Eigen::Vector3d& bg, const Eigen::Vector3d& ba);
  /// Rotates the keyframe's velocity by R (a correction of the map's frame around it); the state
  /// stays as estimated, or not, as it was.
  bool rotateKeyFrameVelocity(KeyFrameId id, const Eigen::Matrix3d& R);
  bool setMapPointPosition(MapPointId id, const Eigen::Vector3d& p_w);
  /// Moves the whole map by the similarity S_new_old: p -> s R p + t (the gravity alignment and
  /// scale of the inertial initialisation, a monocular map's scale normalisation). It acts on the
  /// cameras, not the bodies: the visual map may be at any scale but the camera-to-body offset
  /// (options().T_b_c[0]) is metric, so each body pose follows its camera's transformed pose,
  /// T_w_b' = S (T_w_b T_b_c) T_c_b, which keeps every reprojection unchanged up to the depth
  /// scale. Map points move; normals rotate; distance ranges and velocities scale by s (velocities
  /// also rotate).
  void transformWorld(const Sim3d& S_new_old);
  /// Appends a correction to the map's log (call within the map update that applied it).
  void recordCorrection(MapCorrection correction);
  /// Number of corrections recorded: poses held outside the map that are expressed in the map as
  /// of generation g follow the corrections [g, correctionCount()).
  int correctionCount() const;
  /// The corrections from generation `first` on (empty when none).
  std::vector<MapCorrection> correctionsSince(int first) const;
  /// Stores a copy (clone) of one descriptor row.
  bool setMapPointDescriptor(MapPointId id, const cv::Mat& descriptor);
  /// Sets the point's descriptor to its most representative observation, as ORB-SLAM does: of
  /// the descriptor rows of the observing keyframe keypoints, the one with the smallest median
  /// distance to the others (ties: the oldest keyframe). Distances: Hamming for binary rows
  /// (CV_8UC1, ORB), Euclidean for float rows (CV_32FC1, learned descriptors). False when the
  /// point is unknown or none of its keyframes stores descriptors. Not called by the tracker:
  /// on the synthetic MH_03 run (stereo-inertial) updating tracked points at every keyframe gave
  /// ATE 2.8 cm instead of 2.5 cm with ORB and 37.7 cm instead of 14.1 cm with XFeat, against
  /// keeping the descriptor of the creating keyframe.
  bool updateDescriptor(MapPointId id);
  bool increaseVisible(MapPointId id, int count = 1);
  bool increaseFound(MapPointId id, int count = 1);

  /// Recomputes the point's mean viewing direction (over all observing cameras) and its
  /// scale-invariance distance range from the oldest observing keyframe: with d the distance [m]
  /// from that camera and o the keypoint's octave, max = d * scale^o and
  /// min = max / scale^(num_levels - 1). False when the point is unknown or has no observation.
  bool updateNormalAndDistances(MapPointId id);

  // ---- Queries
  // -----------------------------------------------------------------------------------

  std::size_t numKeyFrames() const;
  /// Including bad points not yet erased.
  std::size_t numMapPoints() const;
  bool hasKeyFrame(KeyFrameId id) const;
  bool hasMapPoint(MapPointId id) const;
  /// Ids in increasing order.
  std::vector<KeyFrameId> keyFrameIds() const;
  /// The ids the next keyframe and point added get (a map continuing this one starts there).
  KeyFrameId nextKeyFrameId() const;
  MapPointId nextMapPointId() const;
  /// The keyframe with the largest id (the newest), kNoKeyFrame when empty.
  KeyFrameId newestKeyFrame() const;
  /// The keyframe whose predecessor is `id` (kNoKeyFrame when none or unknown).
  KeyFrameId nextKeyFrame(KeyFrameId id) const;
  /// Ids of the points that are not bad, in increasing order.
  std::vector<MapPointId> mapPointIds() const;
  /// Points (not bad) whose observing keypoints do not all carry one class_id: a match across
  /// semantic classes made them (class-wise matching never does).
  std::size_t numCrossClassMapPoints() const;

  /// Copies (cv::Mat members share their pixel data with the map's, which the map never writes).
  std::optional<KeyFrame> keyFrame(KeyFrameId id) const;
  std::optional<MapPoint> mapPoint(MapPointId id) const;
  std::optional<SE3d> keyFramePose(KeyFrameId id) const;
  /// The pose of a keyframe of the map, or of one erased from it since: eraseKeyFrame keeps an
  /// erased keyframe as its camera pose relative to an anchor keyframe (its best covisible one,
  /// else its temporal predecessor or successor), so that it follows every later correction of
  /// the anchor (ORB-SLAM keeps a culled keyframe relative to its spanning-tree parent for the
  /// same reason: frames tracked against it are reported through it). nullopt for an id the map
  /// never had, or an erased keyframe that had no keyframe left to anchor it.
  std::optional<SE3d> resolvedKeyFramePose(KeyFrameId id) const;
  std::optional<Eigen::Vector3d> mapPointPosition(MapPointId id) const;

  /// Calls fn(const KeyFrame&) under the map's lock, without copying; false when the id is
  /// unknown. fn must not call this Map (the mutex is not recursive) and must not keep references.
  template <typename Fn>
  bool readKeyFrame(KeyFrameId id, Fn&& fn) const {
    const std::lock_guard lock(mutex_);
    const auto it = keyframes_.find(id);
    if (it == keyframes_.end()) return false;
    fn(it->second);
    return true;
  }
  /// As readKeyFrame(), for a map point.
  template <typename Fn>
  bool readMapPoint(MapPointId id, Fn&& fn) const {
    const std::lock_guard lock(mutex_);
    const auto it = points_.find(id);
    if (it == points_.end()) return false;
    fn(it->second);
    return true;
  }

  // ---- Covisibility graph ----------------------------------------------------------------------

  /// Number of map points observed by both keyframes (0 when unknown or the same keyframe).
  int covisibilityWeight(KeyFrameId a, KeyFrameId b) const;
  /// Keyframes sharing at least min_weight points with `id`, by decreasing weight, ties by
  /// increasing id. Empty when the keyframe is unknown.
  std::vector<CovisibleKeyFrame> covisibleKeyFrames(KeyFrameId id, int min_weight = 1) const;
  /// Ids of the (at most) n keyframes sharing most points with `id`, in the order above.
  std::vector<KeyFrameId> bestCovisibleKeyFrames(KeyFrameId id, int n) const;

  /// Checks every invariant: observations agree on both sides, indices are in range, observed
  /// keypoints are valid() (undistorted), bad points have no observation, and the covisibility
  /// graph is symmetric and equals the one rebuilt from the observations. Returns "" when all hold,
  /// else a description of the first violation.
  std::string consistencyError() const;

 private:
  using CovisibilityRow = std::map<KeyFrameId, int>;

  MapPoint* findPoint(MapPointId id);
  KeyFrame* findKeyFrame(KeyFrameId id);
  void validateKeyFrame(const KeyFrame& keyframe) const;
  /// Adds the observation; both exist, the index is valid and both slots are free.
  void attachObservation(MapPoint& point, KeyFrame& keyframe, int keypoint_index);
  /// Removes the observation of the point in the keyframe (which must exist).
  void detachObservation(MapPoint& point, KeyFrame& keyframe);
  void detachAllObservations(MapPoint& point);
  /// Gives the successor of `erased` (if any) its predecessor and merged IMU samples.
  void relinkSuccessor(const KeyFrame& erased);
  /// Remembers an erased keyframe relative to its anchor (resolvedKeyFramePose).
  void anchorErasedKeyFrame(const KeyFrame& erased);
  std::optional<SE3d> resolvePoseLocked(KeyFrameId id) const;
  void addCovisibility(KeyFrameId a, KeyFrameId b, int delta);
  std::unordered_map<KeyFrameId, CovisibilityRow> rebuildCovisibility() const;
  std::string observationError() const;
  std::string covisibilityError() const;

  MapOptions options_;
  /// Map updates against multi-call readers; taken before mutex_, never while holding it.
  mutable std::shared_mutex update_mutex_;
  mutable std::mutex mutex_;
  std::unordered_map<KeyFrameId, KeyFrame> keyframes_;
  std::unordered_map<MapPointId, MapPoint> points_;
  /// covisibility_[a][b] = points shared by a and b (> 0); symmetric; one row per keyframe.
  std::unordered_map<KeyFrameId, CovisibilityRow> covisibility_;
  /// An erased keyframe: the camera pose T_anchor_c of its left camera in the anchor's.
  struct ErasedKeyFrame {
    KeyFrameId anchor = kNoKeyFrame;
    SE3d T_ca_c;
  };
  std::unordered_map<KeyFrameId, ErasedKeyFrame> erased_;
  std::vector<MapCorrection> corrections_;
  KeyFrameId next_keyframe_id_ = 0;
  KeyFrameId newest_keyframe_ = kNoKeyFrame;
  MapPointId next_point_id_ = 0;
};

}  // namespace superdyna::map

#pragma once
// Loop closing, run after local mapping of each keyframe (ORB-SLAM's loop closing, written anew
// without a vocabulary): SE(3) geometry for stereo and inertial maps, Sim(3) for visual monocular
// maps, whose scale drifts.
//
// 1. Detection: the keyframe's place descriptors query the KeyFrameDatabase (then join it). The
//    keyframes it shares map points with, and those less than min_time_gap_s older, are no
//    candidates; a candidate must score at least as high as the least similar of the query's
//    best covisible keyframes (ORB-SLAM's relative bar) and min_score. Candidates are grouped with
//    their covisible neighbours (accumulated score >= 0.75 of the best group's), and a group is
//    only verified once `consistency` consecutive query keyframes found overlapping groups.
// 2. Verification: the query keyframe's keypoints with 3D (stereo depth, else their map point)
//    are matched by descriptor to the map points of the candidate and its best covisible
//    keyframes; RANSAC on the 3D-3D matches (rigid_ransac.h, inliers by reprojection into the
//    query keyframe) gives the query camera's pose in the loop's frame, refined by motion-only BA;
//    then guided matching by projection and a second motion-only BA. Accepted with at least
//    min_inliers inliers. Inertial maps: the correction must leave roll and pitch within
//    max_roll_pitch_deg (gravity observes them); it is then reduced to yaw and position.
//    Every map: a correction larger than the odometry can have drifted since the match keyframe
//    is a different place that looks the same (perceptual aliasing), not a loop: the query
//    keyframe may turn by at most max_correction_deg and move by at most
//    max_correction_path_share of the path between the match and the query keyframes (plus
//    min_correction_m in metric maps).
//    Monocular maps: the RANSAC fits a similarity (the reprojection test and the motion-only BA
//    do not see the scale), and the loop's scale is the median ratio, over the final inliers, of
//    the loop point's depth in the verified camera to the query's own point's depth.
// 3. Correction: pose graph (pose_graph.h; 4-DoF for inertial maps, 7-DoF Sim(3) for monocular
//    ones, 6-DoF otherwise) over the
//    essential graph: the temporal chain of keyframes (their spanning tree), covisibility edges of
//    at least strong_covisibility shared points, the edges of earlier loops and the new loop's
//    (the query keyframe's group at its corrected poses to the loop keyframe and its group); the
//    loop keyframe is held. Each keyframe moves by its correction C (T_new = C T_old; with a
//    scale, map::KeyFrameCorrection), each map point with its reference (oldest observing)
//    keyframe's, velocities rotate. All of it is one
//    map update (Map::updateLock()) and is recorded in the map (Map::recordCorrection) for the
//    poses held outside it. Keyframes inserted while the graph was optimised move with the newest
//    graph keyframe. Then the loop's duplicated points are fused: the verified matches make the
//    query keyframe observe the loop's points (its own duplicates merged into them), and the
//    PointFuser runs on the query keyframe's group.
// 4. Map merging (with an atlas, setAtlas()): candidates in the maps tracking left go through the
//    same stages 1 and 2 against their own map; the verified one is moved into this map's frame
//    and absorbed, its matches fused as a loop's (mergeMap()).
//
// Features labelled on movable objects (class_id != 0) neither vote nor take part in the
// verification. Threads: one thread calls processKeyFrame(), or findLoop() in one thread and
// closeLoop() in another (the System's concurrent pipeline: a loop thread and the mapping
// thread); recognize() (relocalisation's place recognition) may come from any thread.

#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include "superdyna/core/camera_model.h"
#include "superdyna/core/time.h"
#include "superdyna/loop/keyframe_database.h"
#include "superdyna/loop/pose_graph.h"
#include "superdyna/loop/rigid_ransac.h"
#include "superdyna/map/atlas.h"
#include "superdyna/map/map.h"
#include "superdyna/mapping/point_fusion.h"
#include "superdyna/optim/pose_optimizer.h"
#include "superdyna/optim/reprojection_factor.h"

namespace superdyna::loop {

struct LoopClosingOptions {
  bool enabled = true;  ///< Run loop closing (and with it the atlas and map merging).
  KeyFrameDatabaseOptions database;
  double min_time_gap_s = 10.0;  ///< Candidates are at least this much older [s], >= 0.
  double min_score = 0.02;       ///< Absolute bar on the database score, [0, 1].
  int group_keyframes = 10;      ///< Covisible keyframes of a candidate's group, >= 0.
  int consistency = 3;           ///< Consecutive keyframes that must find a group, >= 1.
  int max_candidates = 3;        ///< Consistent groups verified per keyframe (best first), >= 1.
  /// Keyframes after an accepted loop before the next detection, >= 0.
  int keyframes_between_loops = 5;
  int match_max_hamming = 50;     ///< Descriptor matching bound, binary [bits], >= 0.
  double match_max_l2 = 0.9;      ///< ... float (Euclidean), >= 0.
  double match_ratio = 0.85;      ///< Lowe's ratio test of the descriptor matching, (0, 1].
  RigidRansacOptions ransac;      ///< Its min_inliers: the RANSAC's bar (default 12).
  double ransac_chi2 = 9.21;      ///< Reprojection inlier bound of the RANSAC (chi^2, 2 dof), > 0.
  double guided_radius_px = 8.0;  ///< Search radius of the guided matching [px], > 0.
  int min_inliers = 60;           ///< Inliers after guided matching to accept a loop, >= 3.
  double max_roll_pitch_deg = 2.0;  ///< Inertial maps: largest roll / pitch correction [deg], > 0.
  /// Largest rotation of the query keyframe by the correction [deg], > 0.
  double max_correction_deg = 20.0;
  /// Largest move of the query keyframe by the correction, as a share of the path between the
  /// match and the query keyframes (the keyframes' positions in time order), > 0 ...
  double max_correction_path_share = 0.2;
  double min_correction_m = 0.2;  ///< ... plus this in metric maps [m], >= 0.
  PoseGraphOptions pose_graph;    ///< four_dof / seven_dof are set from the map.
  int strong_covisibility = 100;  ///< Covisibility edges of the essential graph, >= 1.
  bool fuse = true;               ///< Fuse the loop's duplicated points after the correction.
  /// Throws OptionError naming the first invalid field (prefix "loop.").
  void validate() const;
  bool operator==(const LoopClosingOptions&) const = default;
};

/// An accepted loop.
struct LoopClosure {
  map::KeyFrameId query = map::kNoKeyFrame;  ///< The new keyframe that recognised the place.
  map::KeyFrameId match = map::kNoKeyFrame;  ///< The older keyframe it was matched to.
  TimeNs query_t_ns = 0;
  TimeNs match_t_ns = 0;
  /// The verified relative body pose T_match_query (in the match's frame, after the correction).
  SE3d T_match_query;
  int inliers = 0;
  /// The correction of the query keyframe before the pose graph (T_new = C T_old) ...
  SE3d correction;
  double scale = 1.0;  ///< ... and of its scale (Sim(3) loops of monocular maps).
  /// A map merge: `match` was a keyframe of an atlas map, now part of the active map, which took
  /// that map moved by the similarity (scale, correction) from its frame into the active one.
  bool merge = false;
};

/// How far an accepted loop's relative pose is from the true one, T_match_query_true (body
/// frames): the error of the relative pose of the left camera (T_b_c). A Sim(3) loop (scale != 1,
/// a monocular map with its own unit) is judged at the true length. Camera frames, because a
/// monocular map places its bodies by the metric camera-body lever arm in the map's unit.
SE3d loopError(const LoopClosure& loop, const SE3d& T_match_query_true, const SE3d& T_b_c);

/// Why the verification of a candidate stopped.
enum class Rejection {
  kTooFewMatches,  ///< Descriptor matches (or loop points) below the RANSAC's min_inliers.
  kNoTransform,    ///< RANSAC or the first motion-only BA found no pose.
  kTooFewInliers,  ///< Fewer than min_inliers after guided matching.
  kTilted,         ///< Inertial map: the correction would change roll / pitch.
  kBeyondDrift,    ///< The correction is larger than the odometry can have drifted.
};
inline constexpr int kRejectionKinds = 5;

/// A loop that passed the geometric verification, not yet applied to the map.
struct VerifiedLoop {
  map::KeyFrameId query = map::kNoKeyFrame;
  map::KeyFrameId match = map::kNoKeyFrame;
  SE3d T_w_b_query;    ///< The query keyframe's pose in the loop's frame.
  double scale = 1.0;  ///< Monocular maps: a length on the query's side is this long at the loop.
  std::vector<map::KeyFrameId> loop_group;
  /// Inlier matches: query keypoint index -> loop map point.
  std::vector<std::pair<int, map::MapPointId>> matches;
  int inliers = 0;
  /// A merge: the atlas map that holds the match (T_w_b_query is in its frame); null for a loop.
  std::shared_ptr<map::Map> other;
};

/// What one processKeyFrame() (or findLoop()) call did, with its stage times [ms].
struct LoopStep {
  int candidates = 0;                  ///< Consistent groups verified.
  int rejected[kRejectionKinds] = {};  ///< Candidates rejected, by Rejection.
  std::optional<LoopClosure> closure;  ///< processKeyFrame(): the loop applied.
  std::optional<VerifiedLoop> found;   ///< findLoop(): the loop verified, to apply.
  double detection_ms = 0.0;
  double verification_ms = 0.0;
  double correction_ms = 0.0;  ///< Pose graph, point correction and fusion.
};

class LoopCloser {
 public:
  /// camera0: the left camera (projection for guided matching); camera: the same as a
  /// reprojection camera in the body frame (its baseline enables stereo observations);
  /// monocular: the map has one camera (without an IMU its loops are Sim(3)). Validates the
  /// options.
  LoopCloser(const LoopClosingOptions& options, const CameraModel& camera0,
             const optim::ReprojectionCamera& camera, const mapping::PointFusionOptions& fusion,
             const optim::PoseOptimizerOptions& pose, bool monocular = false);

  /// Detects, verifies and corrects a loop at `keyframe` (a keyframe of `map` local mapping has
  /// processed): findLoop() then closeLoop(). inertial: the map is gravity-aligned (4-DoF).
  LoopStep processKeyFrame(map::Map& map, map::KeyFrameId keyframe, bool inertial);

  /// Stages 1 and 2 only (the map is read, not changed): the keyframe joins the database and a
  /// loop found at it is returned in `found`, to be applied with closeLoop(). After a found loop
  /// detection rests for keyframes_between_loops keyframes, whether or not it gets applied.
  LoopStep findLoop(const map::Map& map, map::KeyFrameId keyframe, bool inertial);
  /// Stage 3: corrects the map with a verified loop (pose graph, points, fusion) and adds its
  /// edges to later pose graphs. Changes the map: call it where local mapping runs. It may run
  /// while findLoop() runs in another thread (they share no state); the keyframes may have moved
  /// a little since the verification (the query keyframe then lands on its verified pose).
  /// nullopt when the query or the match keyframe has been culled since.
  std::optional<LoopClosure> closeLoop(map::Map& map, const VerifiedLoop& loop, bool inertial);

  /// Forgets the database and the loops (the map was dropped), but for the keyframes of the
  /// atlas maps: their places are still recognised, for merges.
  void reset();
  /// The maps tracking left (not owned, must outlive its use; nullptr = none). A keyframe
  /// that recognises a place of one of them (detected, grouped, made consistent and verified as
  /// a loop, with the candidate's points and covisibility taken from its map and no drift bound:
  /// the two maps' frames are unrelated) merges it: closeLoop() takes that map from the atlas,
  /// moves it into the active map's frame by the verified relative pose (rigid; a similarity in
  /// visual monocular maps; yaw and position in inertial ones), absorbs it (map::Map::absorb) and
  /// fuses the matched points, as a loop's; the active map's own keyframes do not move.
  void setAtlas(map::Atlas* atlas) { atlas_ = atlas; }

  /// The indexed keyframes whose places score best against `rows` (placeDescriptorRows of a
  /// frame), best first, at most `count`. Thread-safe against processKeyFrame() and reset(): the
  /// tracker relocalises with it while loop closing runs in the mapping thread.
  std::vector<PlaceScore> recognize(const cv::Mat& rows, int count) const;

  /// The database: read it only from the thread that calls processKeyFrame() / findLoop().
  const KeyFrameDatabase& database() const { return database_; }
  const LoopClosingOptions& options() const { return options_; }

 private:
  struct Candidate;
  struct Group {
    std::vector<map::KeyFrameId> members;  ///< Sorted.
    int consistency = 0;
  };
  /// Loop candidates in the map, then merge candidates in the atlas maps.
  std::vector<Candidate> detect(const map::Map& map, const map::KeyFrame& query);
  /// The candidates of `passed` (keyframe -> score, all of `map`) grouped with their best
  /// covisible neighbours; groups scoring below 0.75 of the best one are dropped.
  std::vector<Candidate> groupCandidates(const map::Map& map,
                                         const std::map<map::KeyFrameId, double>& passed) const;
  /// Merge candidates: keyframes of atlas maps scoring at least `bar`, grouped per map.
  std::vector<Candidate> mergeCandidates(const std::vector<PlaceScore>& scores, double bar) const;
  /// Indexes the map's keyframes older than `first` (the first keyframe the closer is given):
  /// an inertial map reaches the closer only once its initialisation stages have run, and the
  /// places it saw before must be found again too.
  void indexEarlierKeyFrames(const map::Map& map, map::KeyFrameId first);
  /// KeyFrameDatabase::settle() with the map's keyframes at the query's time `now_ns`.
  void settleDatabase(const map::Map& map, TimeNs now_ns);
  std::vector<Candidate> consistentCandidates(const map::Map& map,
                                              const std::vector<Candidate>& groups);
  /// The verified loop, or nullopt with `rejection` set.
  /// match_map: the candidate's map (`map` for a loop, an atlas map for a merge).
  std::optional<VerifiedLoop> verify(const map::Map& map, const map::Map& match_map,
                                     const map::KeyFrame& query, map::KeyFrameId candidate,
                                     bool inertial, Rejection& rejection) const;
  /// Whether moving the query keyframe from its pose to T_w_b_new stays within what the odometry
  /// can have drifted since the match keyframe (max_correction_*).
  bool withinDrift(const map::Map& map, const map::KeyFrame& query, map::KeyFrameId match,
                   const SE3d& T_w_b_new, bool inertial) const;
  /// False when the query or the match keyframe is gone (nothing changed).
  bool correct(map::Map& map, const VerifiedLoop& loop, bool inertial);
  void fuseLoop(map::Map& map, const VerifiedLoop& loop) const;
  /// closeLoop() of a merge; false when the atlas map or the query keyframe is gone.
  bool mergeMap(map::Map& map, const VerifiedLoop& loop, LoopClosure& closure);
  /// Whether loops of the map are similarities: monocular without the IMU's scale.
  bool similarity(bool inertial) const { return monocular_ && !inertial; }

  LoopClosingOptions options_;
  bool monocular_ = false;
  CameraModel camera0_;
  optim::ReprojectionCamera camera_;
  mapping::PointFuser fuser_;
  optim::PoseOptimizer pose_optimizer_;
  KeyFrameDatabase database_;
  /// Held over each use of database_ (never while waiting for the map): recognize() comes from
  /// another thread.
  mutable std::mutex database_mutex_;
  std::vector<Group> groups_;  ///< Consistent groups of the previous keyframe.
  std::vector<PoseGraphEdge> loop_edges_;
  int keyframes_since_loop_ = 0;
  bool had_loop_ = false;
  bool indexed_earlier_ = false;  ///< indexEarlierKeyFrames() ran for the current map.
  map::Atlas* atlas_ = nullptr;
};

}  // namespace superdyna::loop

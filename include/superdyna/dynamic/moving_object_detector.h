#pragma once
// The moving-object test (the paper's D module, stage 2): of the movable objects the instance
// masks label (stage 1: keypoints with class_id != background), which ones move between the
// previous and the current frame, and so which keypoints tracking must not use.
//
// Per frame, given the predicted relative camera pose T_cur_prev (IMU preintegration or the motion
// model; the tracker's prediction):
// 1. Pairs. Background keypoints of the previous frame are matched into the current frame around
//    where a static point lands (its stereo point moved by the prediction, or without depth its
//    bearing rotated, in a doubled radius); keypoints of movable objects within a wide radius
//    around that place (object_search_radius_px: a mover's own image motion), class-wise.
// 2. Motion. With stereo, the prediction is refined on the background pairs (refine_motion,
//    relative_motion.h): its velocity error would make near static objects look moving.
// 3. Threshold. Every background pair's residual (motion_residual.h) under each test, divided by
//    the pair's keypoint scale (scale_factor^octave of its coarser keypoint: an ORB corner found
//    at octave 4 is only located to about 2 px); the threshold of a test is max(min_threshold_px,
//    threshold_scale * median scaled background residual), times the scale of the pair tested.
//    The paper takes the mean background distance; the median ignores the background's own
//    mismatches and unlabelled movers. Too few background pairs: fallback_threshold_px.
// 4. Objects. The pairs of each current instance are grouped. An object with fewer than min_pairs
//    of them (background_pairs_for_new_objects) is also paired with the previous frame's
//    background keypoints that would land in its box if they stood still: a segmenter on real
//    images labels an object in one frame and not in the next (a false detection on a building,
//    a parked car it misses every other frame), and without pairs such an object could only be
//    dropped unverified. Such pairs can only clear an object: found moving on them, it keeps its
//    track's state (unverified for a new one) and the map points of those background keypoints
//    stay, since the background they come from may be what the object now hides. Objects still
//    with fewer than min_pairs are unverified this frame.
//    Otherwise up to max_tested_pairs pairs are drawn (seeded, so that deterministic runs stay
//    bit-identical) and tested, each over the longest baseline it has (up to baseline_frames): a
//    pair whose previous keypoint continues pairs of the frames before is tested from the earliest
//    of them, with the chained refined motion and thresholds from the background's links over the
//    same frames. The longest links are drawn first, shorter ones fill the room left. Test:
//    reprojection where the earlier keypoint has stereo depth (stereo_reprojection), else epipolar
//    (the distance to the part of the line a static point at positive depth can reach,
//    motion_residual.h), or rotation transfer when the predicted translation is below
//    min_translation_m. The object moves in this frame when at least max(min(min_votes, tested),
//    ceil(moving_vote_share * tested)) tested pairs exceed the threshold of their test (the paper:
//    any one pair). With skip_border_pairs, pairs with a keypoint on the object's mask border
//    (features::Keypoint::on_instance_border) are left out when the object has others: such a
//    corner is formed with the background behind the silhouette and slides along it as the camera
//    moves, and its stereo depth may be the background's (a parked car's border pairs were 6-8 px
//    off under stereo reprojection while its inner pairs were within 1 px).
// 5. Identity and hysteresis. Network segmenters do not keep instance ids across frames, so an
//    object inherits the track of the previous instance most of its pairs come from (greedily,
//    strongest links first, each previous track to one object; an object with no pairs to a
//    tracked object takes the track of the one whose keypoints land on it; a new track when
//    none; on a simulated parking lot this keeps 1.4 % more of the static objects' keypoints). A
//    new track takes its first frame's verdict; a static track turns moving after
//    moving_confirmations moving frames in a row, a moving one static after static_confirmations
//    static frames in a row, or at once after a frame in which clear_static_pairs or more pairs
//    were tested and none exceeded its threshold; unverified frames, and for a verified track
//    frames with fewer than min_votes tested pairs (one pair may be a mismatch), keep the state.
//    Keypoints of moving tracks are dropped, those of never-verified ones too when
//    drop_unverified.
//
// mode kSemantic drops every movable keypoint (DynaSLAM-style) without testing; kOff drops none.
//
// `geometric` (on top of any mode) catches movers the segmenter does not label (the paper's
// failure case: a shopping cart): the background pairs are tested like an object's, grouped into
// image cells of geometric_cell_px, and every background keypoint in a cell where at least
// geometric_min_outliers pairs, and geometric_outlier_share of the cell's pairs, exceed
// geometric_threshold_factor times their threshold is dropped.

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <vector>

#include "superdyna/core/camera_model.h"
#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"
#include "superdyna/dynamic/motion_residual.h"
#include "superdyna/features/feature_set.h"

namespace superdyna::dynamic {

enum class DynamicMode { kOff, kSemantic, kSemanticGeometric };
/// "off" | "semantic" | "semantic-geometric"; OptionError naming `option` otherwise.
DynamicMode parseDynamicMode(const std::string& name, const std::string& option);
std::string toString(DynamicMode mode);

inline constexpr int kMaxBaselineFrames = 4;

struct MovingObjectOptions {
  DynamicMode mode = DynamicMode::kOff;
  int min_pairs = 1;                   ///< Fewer pairs: unverified this frame, >= 1.
  int max_tested_pairs = 10;           ///< Pairs drawn per object, >= 1.
  bool skip_border_pairs = true;       ///< Test the pairs off the mask border first (above).
  double threshold_scale = 2.5;        ///< Times the median background residual, > 0.
  double min_threshold_px = 1.0;       ///< Lower bound of a threshold [px], > 0.
  double fallback_threshold_px = 3.0;  ///< Threshold without enough background pairs [px], > 0.
  int min_background_pairs = 20;       ///< Background pairs a test's threshold needs, >= 1.
  double moving_vote_share = 0.35;     ///< Share of tested pairs beyond the threshold, (0, 1].
  int min_votes = 2;                   ///< ... and at least this many (capped by tested), >= 1.
  double min_translation_m = 0.01;     ///< Below: rotation transfer instead of epipolar, >= 0.
  bool stereo_reprojection = true;     ///< Test pairs with previous stereo depth by reprojection.
  /// Refine the predicted relative pose on the background pairs with stereo depth before testing
  /// (relative_motion.h); without stereo the prediction is used as it is.
  bool refine_motion = true;
  int static_confirmations = 2;  ///< Static frames in a row that clear a moving track, >= 1.
  /// A static frame in which at least this many pairs were tested and none exceeded its
  /// threshold clears a moving track at once (an agent that stopped); 0 = never, >= 0.
  int clear_static_pairs = 3;
  int moving_confirmations = 2;  ///< Moving frames in a row that set a static track, >= 1.
  bool drop_unverified = true;   ///< Drop objects never verified (new, too few pairs).
  /// Pair an object that has too few pairs among the previous frame's objects with the previous
  /// frame's background keypoints in its place (see the file comment, step 4).
  bool background_pairs_for_new_objects = true;
  /// The tracker also culls the local map's points whose instance id is that of a moving object:
  /// right when instance ids are stable over the sequence (dataset masks); `superdyna run` turns it
  /// off for other segmenters, which renumber instances every frame (then only the points of the
  /// moving object's pairs in the previous frame are culled).
  bool cull_points_by_instance = true;
  double background_radius_px = 20.0;      ///< Search radius of background pairs [px], > 0.
  double object_search_radius_px = 120.0;  ///< Search radius of object pairs [px], > 0.
  double match_ratio = 0.8;                ///< Ratio test of both searches, (0, 1].
  /// Fastest motion of a pedestrian / a vehicle or other movable object [m/s], > 0. A pair whose
  /// stereo point would have moved faster between the frames (at least its residual over the
  /// focal length times its depth, over the time between the frames) is a mismatch of the wide
  /// object search and is not tested.
  double max_pedestrian_speed_mps = 4.0;
  double max_vehicle_speed_mps = 40.0;
  int max_hamming = 64;          ///< Largest accepted Hamming distance [bits], >= 0.
  double max_l2_distance = 1.0;  ///< Largest accepted float distance, >= 0.
  int seed = 1;  ///< Seeds the draw of tested pairs (mixed with the frame time), >= 0.
  /// Up to how many frames back a pair is tested, in [1, kMaxBaselineFrames]: a pair that
  /// continues pairs of the frames before is tested from the earliest of them (n frames multiply
  /// a slow mover's displacement by n); 1: the last frame only (the paper).
  int baseline_frames = 2;
  /// The geometric test of background features, on top of any mode (see the file comment).
  bool geometric = false;
  int geometric_cell_px = 48;            ///< Image cells the outliers are grouped in [px], >= 8.
  int geometric_min_outliers = 3;        ///< Outlying background pairs a moving cell needs, >= 1.
  double geometric_outlier_share = 0.5;  ///< ... and this share of its tested pairs, (0, 1].
  /// A background pair is outlying beyond this many times its test's threshold, >= 1.
  double geometric_threshold_factor = 2.0;
  void validate() const;
  bool operator==(const MovingObjectOptions&) const = default;
};

/// One frame as the test reads it (views into the caller's data, which must outlive the call).
struct FrameObservations {
  TimeNs t_ns = 0;
  const features::FeatureSet* features = nullptr;
  /// Undistorted normalised coordinates per keypoint; NaN when undistortion failed.
  const std::vector<Eigen::Vector2d>* normalized = nullptr;
  /// Stereo point in the camera per keypoint [m]; valid where depth_m[i] > 0. May be null (mono).
  const std::vector<Eigen::Vector3d>* p_c = nullptr;
  const std::vector<double>* depth_m = nullptr;
  bool hasDepth(std::size_t i) const { return depth_m && (*depth_m)[i] > 0.0; }
};

enum class ObjectState { kUnverified, kStatic, kMoving };
const char* toString(ObjectState state);

/// The verdict on one movable instance of the current frame.
struct ObjectDecision {
  int instance_id = 0;
  int class_id = 0;
  int track_id = -1;  ///< Identity across frames (see the file comment); -1 in kSemantic.
  int keypoints = 0;  ///< Its keypoints in the current frame.
  int pairs = 0;      ///< Its keypoints matched to the previous frame.
  int tested = 0;     ///< Pairs drawn and tested this frame (0: unverified or kSemantic).
  int votes = 0;      ///< Tested pairs beyond their threshold.
  double max_distance_px = 0.0;  ///< Largest tested residual.
  double threshold_px = 0.0;     ///< Threshold of the test of that pair.
  /// The state applied (after hysteresis); kMoving for every object in kSemantic.
  ObjectState decision = ObjectState::kUnverified;
  bool dropped = false;  ///< Its keypoints are dropped.
};

struct MovingObjectReport {
  std::vector<ObjectDecision> objects;  ///< One per movable instance, by instance id.
  std::vector<char> drop;               ///< Per current keypoint: 1 = not to be used.
  /// Previous-frame keypoints paired with keypoints of moving objects (their map points are to
  /// be culled).
  std::vector<int> moving_previous_keypoints;
  int background_pairs = 0;
  int dropped = 0;                  ///< Keypoints with drop set.
  int moving_background_cells = 0;  ///< Image cells the geometric test found moving.
  int geometric_dropped = 0;        ///< Background keypoints dropped in those cells.
};

class MovingObjectDetector {
 public:
  /// `camera` is the camera both frames come from (projection of predicted points);
  /// `pyramid_scale_factor` the extractor's scale step between octaves (residuals are compared in
  /// units of the coarser keypoint's scale, see the file comment).
  MovingObjectDetector(const MovingObjectOptions& options, const CameraModel& camera,
                       double pyramid_scale_factor = 1.2);

  /// The decisions for `current`; `previous` may be null (first frame of a map: nothing is tested).
  /// T_cur_prev maps previous-camera points into the current camera.
  MovingObjectReport detect(const FrameObservations* previous, const FrameObservations& current,
                            const SE3d& T_cur_prev);
  /// Forgets every track (a new map).
  void reset();
  const MovingObjectOptions& options() const { return options_; }

 private:
  struct Track {
    ObjectState state = ObjectState::kUnverified;
    int static_run = 0;  ///< Static frames in a row.
    int moving_run = 0;  ///< Moving frames in a row.
  };
  struct Pair {
    int previous = 0;
    int current = 0;
  };
  /// Per residual test: its threshold [px, before the pair's scale] and the background residuals
  /// it came from.
  struct Thresholds {
    std::array<double, kResidualTestCount> px{};
    std::array<int, kResidualTestCount> samples{};
  };
  /// A keypoint of an earlier frame, as far as the tests need it.
  struct Endpoint {
    Eigen::Vector2d x = Eigen::Vector2d::Zero();  ///< Normalised coordinates.
    Eigen::Vector3d p = Eigen::Vector3d::Zero();  ///< Stereo point (when has_depth).
    bool has_depth = false;
    int octave = 0;
    bool on_border = false;  ///< features::Keypoint::on_instance_border.
  };
  /// An earlier keypoint and the current keypoint it became.
  struct Link {
    Endpoint from;
    int current = 0;
  };
  /// The motion from an earlier frame and the thresholds of its tests.
  struct Baseline {
    SE3d T_cur_from;
    Thresholds thresholds;
    double dt_s = 0.0;  ///< Time between the two frames (<= 0: unknown).
  };
  Endpoint endpointOf(const FrameObservations& frame, int i) const;
  std::vector<Link> linksOf(const std::vector<Pair>& pairs,
                            const FrameObservations& previous) const;
  /// How many frames before the last one a pair's previous keypoint is chained back.
  int chainDepth(const Pair& pair) const;
  /// The pairs as links from `depth` frames before the last one (0: from the last frame; deeper:
  /// from the chained keypoints of the pairs whose chain reaches that far).
  std::vector<Link> linksAtDepth(const std::vector<Pair>& pairs, const FrameObservations& previous,
                                 int depth) const;
  /// Per depth (0: the last frame, d: d frames before it, while chains reach), the motion to the
  /// current frame and the thresholds of the background's links over it.
  std::vector<Baseline> baselinesOf(const std::vector<Pair>& background,
                                    const FrameObservations& previous,
                                    const FrameObservations& current, const SE3d& T_cur_prev) const;
  /// Chains the current keypoints of `pairs` back through their previous keypoints (up to
  /// baseline_frames - 1 frames) for the next frame.
  void rememberChains(const std::vector<Pair>& pairs, const FrameObservations& previous,
                      const FrameObservations& current, const SE3d& T_cur_prev);

  /// The position uncertainty of a link relative to level 0: scale_factor^octave of its coarser
  /// keypoint.
  double linkScale(const Link& link, const FrameObservations& current) const;
  /// Where previous keypoint `i` lands in the current image if it stands still: its stereo point
  /// moved by T_cur_prev, or without depth its bearing rotated; none when it leaves the image or
  /// its undistortion failed.
  std::optional<Eigen::Vector2d> staticLanding(const FrameObservations& previous, std::size_t i,
                                               const SE3d& T_cur_prev) const;
  /// Pairs of the previous frame's background (`movable` false) or object keypoints, searched
  /// around where a static point lands within background_radius_px or, `wide`,
  /// object_search_radius_px; previous keypoints in `already` are not searched again.
  std::vector<Pair> matchPairs(const FrameObservations& previous, const FrameObservations& current,
                               const SE3d& T_cur_prev, bool movable, bool wide,
                               const std::vector<Pair>& already) const;
  /// Pairs of the previous keypoints marked in `query`, searched among the current keypoints
  /// marked in `candidate` within `radius_px` of where a static point lands.
  std::vector<Pair> searchPairs(const FrameObservations& previous, const FrameObservations& current,
                                const SE3d& T_cur_prev, const std::vector<char>& query,
                                std::vector<char> candidate, double radius_px,
                                bool same_class_only) const;
  /// Objects with fewer than min_pairs pairs to the previous frame's movable keypoints (a new
  /// detection, true or false) are paired with the previous frame's background keypoints that
  /// would land in their box if they stood still (background_pairs_for_new_objects). Returns the
  /// objects that got such pairs.
  std::set<int> addBackgroundPairsOfUnpairedObjects(
      const FrameObservations& previous, const FrameObservations& current, const SE3d& T_cur_prev,
      std::map<int, std::vector<Pair>>& pairs_of) const;
  /// T_cur_prev refined on the background pairs with previous stereo depth (relative_motion.h).
  SE3d refinedMotion(const std::vector<Pair>& background, const FrameObservations& previous,
                     const FrameObservations& current, const SE3d& T_cur_prev) const;
  Thresholds backgroundThresholds(const std::vector<Link>& links, const FrameObservations& current,
                                  const SE3d& T_cur_from) const;
  /// The residual of a link under its test and the threshold it is compared with [px].
  std::optional<std::pair<double, double>> linkResidual(const Link& link,
                                                        const FrameObservations& current,
                                                        const SE3d& T_cur_from,
                                                        const Thresholds& thresholds) const;
  void testObjects(const std::map<int, std::vector<Pair>>& pairs_of,
                   const FrameObservations& previous, const FrameObservations& current,
                   const std::vector<Baseline>& baselines,
                   std::map<int, ObjectDecision>& objects) const;
  /// Per image cell (row-major, geometric_cell_px): whether its background pairs move.
  std::vector<char> movingBackgroundCells(const std::vector<Link>& background,
                                          const FrameObservations& current, const SE3d& T_cur_prev,
                                          const Thresholds& thresholds,
                                          MovingObjectReport& report) const;
  /// The geometric test's cells (geometric_cell_px) over an image: columns x rows, their number,
  /// and the row-major index of a pixel's cell (pixels outside fall into the border cells).
  cv::Size cellGrid(cv::Size image_size) const;
  std::size_t cellCount(cv::Size image_size) const;
  std::size_t cellOf(const Eigen::Vector2d& pixel, cv::Size image_size) const;
  void dropKeypoints(const std::map<int, ObjectDecision>& objects,
                     const std::vector<char>& moving_cells, const FrameObservations& current,
                     MovingObjectReport& report) const;
  /// The links an object is tested on: those off the mask border when it has any
  /// (skip_border_pairs), else all.
  std::vector<Link> testableLinks(const std::vector<Link>& links,
                                  const FrameObservations& current) const;
  /// The links whose stereo point would have moved faster than the object's class can
  /// (max_pedestrian_speed_mps, max_vehicle_speed_mps): mismatches of the wide search.
  std::vector<Link> plausibleLinks(const std::vector<Link>& links, const FrameObservations& current,
                                   const Baseline& baseline, int class_id) const;
  /// Draws up to `max_tested` of the links (testable and plausible) and adds their tests to
  /// `decision`.
  void testObject(const std::vector<Link>& links, const FrameObservations& current,
                  const Baseline& baseline, std::uint64_t draw_seed, int max_tested,
                  ObjectDecision& decision) const;
  /// The track of every current instance (`instances`) from its pairs' previous instances;
  /// objects without pairs to a tracked object by overlap (inheritTracksByOverlap).
  std::map<int, int> associateTracks(const std::map<int, std::vector<Pair>>& pairs_of,
                                     const std::vector<int>& instances,
                                     const FrameObservations* previous,
                                     const FrameObservations& current, const SE3d& T_cur_prev);
  /// Current objects that no pair links to a previous object (all their keypoints new: the object
  /// came out from behind another, or came closer) inherit the track of the previous object of
  /// their class whose keypoints, moved as static points by T_cur_prev, mostly land in their
  /// keypoints' box widened by background_radius_px (the most such keypoints wins; each previous
  /// object hands on one track). Without this they would start unverified and be dropped.
  void inheritTracksByOverlap(const FrameObservations& previous, const FrameObservations& current,
                              const SE3d& T_cur_prev, std::set<int>& handed_on,
                              std::map<int, int>& track_of_instance) const;
  /// A frame's verdict that clears a moving track at once (clear_static_pairs).
  bool clearlyStatic(const ObjectDecision& decision) const;
  void applyHysteresis(ObjectDecision& decision, bool tested_moving);
  /// The decision and drop of an object from its track's state as it is.
  void applyTrackState(ObjectDecision& decision);
  /// Keeps only the tracks of the current frame's objects (an object is followed from one frame
  /// to the next only).
  void forgetUnseenTracks(const std::map<int, int>& track_of_instance);

  MovingObjectOptions options_;
  CameraModel camera_;
  double focal_px_ = 1.0;
  double pyramid_scale_factor_ = 1.2;
  std::map<int, Track> tracks_;
  /// A keypoint's partners in the frames before it, newest first.
  struct Chain {
    std::array<Endpoint, kMaxBaselineFrames - 1> ends;
    int size = 0;
  };
  /// A frame before the last one.
  struct EarlierFrame {
    TimeNs t_ns = 0;
    SE3d T_last_from;  ///< The refined motion from it to the last frame.
  };
  std::vector<Chain> chains_;          ///< Per keypoint of the last frame.
  std::vector<EarlierFrame> earlier_;  ///< [d]: d + 1 frames before the last one.
  std::map<int, int> track_of_previous_instance_;
  int next_track_ = 0;
};

}  // namespace superdyna::dynamic

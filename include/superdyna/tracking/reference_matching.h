#pragma once
// Pose of a frame from the map points of one keyframe without a pose prediction (ORB-SLAM's
// TrackReferenceKeyFrame, with exhaustive descriptor matching in place of a bag of words).
//
// Tracking normally matches the local map by projection around a predicted pose. When the motion
// is unknown (the first frame after a new map, before anything gives a velocity) or that search
// fails, the prediction can be wrong by far more than the search radius. Learned descriptors make
// it worse: sampled from a 1/8-resolution map, a wrong keypoint a few pixels from the true one
// looks alike, so the projection search happily returns matches that pull the pose back towards
// the wrong prediction (synthetic V1_03 at 2 m/s: XFeat estimated 1.6 cm for a 9.7 cm step).
//
// Here the keyframe's keypoints that observe map points are matched to the frame exhaustively
// (mutual nearest neighbours with the ratio test, within one semantic class), and a RANSAC PnP on
// the 3D-2D correspondences gives a pose that does not depend on any prediction. The tracker then
// runs its usual local-map search from that pose.

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/features/feature_set.h"
#include "superdyna/features/matcher.h"
#include "superdyna/tracking/frame.h"

namespace superdyna::tracking {

/// Mutual nearest neighbours, ratio 0.8, Hamming <= 64 bits / L2 <= 1, rotation-consistency check
/// for oriented keypoints (ORB).
inline features::BruteForceMatchOptions defaultReferenceMatching() {
  features::BruteForceMatchOptions options;
  options.check_orientation = true;
  return options;
}

/// YAML: the `tracker` section's reference_* keys (reference_matching, reference_max_distance,
/// reference_max_l2_distance, reference_ratio, reference_ransac_threshold_px,
/// reference_search_radius_px, reference_min_inliers).
struct ReferenceMatchingOptions {
  /// Use it for frames whose motion is unknown and as a retry before a frame is declared lost.
  bool enabled = true;
  /// Class-wise as features.class_wise_matching (set by the System).
  features::BruteForceMatchOptions matching = defaultReferenceMatching();
  double ransac_threshold_px = 3.0;  ///< PnP inlier bound [px, at the mean focal], > 0.
  int ransac_iterations = 200;       ///< > 0.
  double ransac_confidence = 0.999;  ///< In (0, 1).
  /// Local-map search radius around the projections from the PnP pose [px], > 0. Tighter than the
  /// usual 15 px: the pose is good to a few pixels, and a wide search lets XFeat's look-alike
  /// neighbours drag it away again (synthetic dim V1_03, frame 1: PnP 9.2 cm of the true 9.6 cm
  /// step; after a 15 px search 2.7 cm, after a 5 px search 8.6 cm).
  double search_radius_px = 5.0;
  /// Support a reference pose needs: PnP inliers, and pose inliers of the local-map search from it,
  /// >= 3 (ORB-SLAM accepts a relocalisation with 50). More than ordinary tracking needs
  /// (tracker.min_inliers): a wrong PnP pose that a few look-alike matches confirm is worse than a
  /// lost frame (with 15, dim and blurred XFeat runs went on with poses metres off).
  int min_inliers = 50;

  void validate() const;
  bool operator==(const ReferenceMatchingOptions&) const = default;
};

/// The map points a keyframe observes: row i of features (keypoint, descriptor) sees p_w[i].
struct ReferenceView {
  features::FeatureSet features;
  std::vector<Eigen::Vector3d> p_w;
};

struct ReferencePose {
  SE3d T_w_b;       ///< Body pose of the frame.
  int matches = 0;  ///< Descriptor matches the PnP ran on.
  int inliers = 0;  ///< PnP inliers.
};

/// The frame's body pose from the view's points, or nullopt when fewer than options.min_inliers
/// matches or PnP inliers support one. `T_b_c0`: cam0 in the body frame; `focal_px` converts
/// the RANSAC bound to the normalised coordinates the frame's keypoints carry. Deterministic.
std::optional<ReferencePose> poseFromReference(const Frame& frame, const ReferenceView& view,
                                               const SE3d& T_b_c0, double focal_px,
                                               const ReferenceMatchingOptions& options);

}  // namespace superdyna::tracking

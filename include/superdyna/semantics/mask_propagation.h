#pragma once
// Mask propagation: the instance masks of a frame that was not segmented, carried over from the
// frame before it through their keypoint matches (SegmenterOptions::every_n_frames). The left
// keypoints of the new frame are matched to the reference frame's (class-agnostic, within a
// radius of where the last image motion puts them); every instance of the reference mask moves
// by the median image motion of its own matched keypoints (the median of all matches when it has
// fewer than `min_instance_matches`), so the new frame's keypoints, the moving-object test and
// the overlay see the objects where they are now. New objects appear only with the next
// segmented frame. The right image is not propagated: stereo points take their left keypoint's
// label, as with SegmenterOptions::right_labels "left".

#include <Eigen/Core>
#include <map>
#include <opencv2/core.hpp>
#include <optional>

#include "superdyna/features/feature_set.h"
#include "superdyna/sensors/instance_masks.h"

namespace superdyna::semantics {

struct PropagationOptions {
  /// Radius [px] of the match search around where the reference keypoint is expected (its pixel
  /// moved by the last frame's median motion), > 0. A search with twice the radius follows when
  /// fewer than `min_matches` are found.
  double radius_px = 40.0;
  int max_hamming = 64;          ///< Largest accepted Hamming distance [bits] (binary descriptors).
  double max_l2 = 0.9;           ///< Largest accepted Euclidean distance (float descriptors).
  double ratio = 0.8;            ///< Best / second-best distance bound, in (0, 1].
  int min_matches = 20;          ///< Fewer matches than this: the wider search (see radius_px).
  int min_instance_matches = 3;  ///< An instance moves by its own median motion from this many.
  void validate() const;         ///< OptionError naming the field (semantics.propagation_*).
  bool operator==(const PropagationOptions&) const = default;
};

/// What one propagation step found, for logs and tests.
struct PropagationStats {
  int matches = 0;  ///< Keypoint matches to the reference frame.
  Eigen::Vector2d median_motion = Eigen::Vector2d::Zero();  ///< Of all matches [px].
  int instances_own_motion = 0;     ///< Instances moved by their own matches' median.
  int instances_common_motion = 0;  ///< Instances moved by the median of all matches.
};

/// Carries masks from frame to frame. Not thread-safe; one per front end.
class MaskPropagator {
 public:
  explicit MaskPropagator(const PropagationOptions& options = {});

  /// Makes a frame (segmented or propagated) the reference of the next propagation: its masks
  /// (only cam0 and the classes are used) and its left features, labelled with those masks
  /// (copied: no buffer is shared with `left`).
  void setReference(const sensors::InstanceMasks& masks, const features::FeatureSet& left);
  bool hasReference() const { return reference_masks_.has_value(); }

  /// The masks of a frame whose left features are `left` (same descriptor type as the
  /// reference's), propagated from the reference. Requires hasReference(). cam1 is left empty.
  sensors::InstanceMasks propagate(const features::FeatureSet& left,
                                   PropagationStats* stats = nullptr);

 private:
  PropagationOptions options_;
  std::optional<sensors::InstanceMasks> reference_masks_;
  features::FeatureSet reference_features_;
  Eigen::Vector2d last_motion_ = Eigen::Vector2d::Zero();  ///< Median motion of the last step.
};

/// The id image with each instance's pixels moved by its integer shift (instances without an
/// entry stay in place); pixels moved outside the image are lost, and where shifted instances
/// overlap the larger id wins. `ids` is CV_16UC1.
cv::Mat shiftInstances(const cv::Mat& ids, const std::map<int, Eigen::Vector2i>& shifts);

}  // namespace superdyna::semantics

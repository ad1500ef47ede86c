#pragma once
// The front end: turns one FrameBundle (images + IMU samples) into a Frame ready for tracking —
// feature extraction on the left image and, with a right camera, stereo matching that gives
// keypoints a depth. It holds no map state, so it can run one frame ahead of tracking in its own
// thread.
//
// The extractor is chosen by FeatureOptions (ORB, XFeat, SuperPoint); the stereo matcher follows
// its descriptor type. When the bundle carries instance masks, every keypoint is labelled with the
// instance under it and that instance's class (no mask: background, 0); with class-wise matching
// the stereo matcher pairs only keypoints of one class. When the masks cover the left image only
// (a segmenter run on the left image), stereo matching ignores classes and a right partner counts
// as having its left keypoint's label. Keypoints on objects are kept: removing dynamic ones is a
// later stage's decision.
//
// With parallel_extraction the right image is extracted on a helper thread while the calling
// thread extracts the left one (each image has its own extractor, so the features are the same
// as when extracting one after the other).

#include <functional>
#include <memory>
#include <optional>

#include "superdyna/core/camera_model.h"
#include "superdyna/core/task_thread.h"
#include "superdyna/features/extractor_factory.h"
#include "superdyna/features/stereo_matcher.h"
#include "superdyna/sensors/calibration.h"
#include "superdyna/sensors/frame_bundle.h"
#include "superdyna/sensors/instance_masks.h"
#include "superdyna/tracking/frame.h"

namespace superdyna::tracking {

struct FrontEndOptions {
  /// Extractor of both cameras; class_wise_matching reaches the stereo matcher through
  /// stereo.same_class_only (system::applyClassWiseMatching).
  features::FeatureOptions features;
  features::StereoMatchOptions stereo;  ///< Left-right matching.
  /// Stereo: extract the right image on a helper thread while the left one is extracted.
  bool parallel_extraction = true;
  void validate() const;
  bool operator==(const FrontEndOptions&) const = default;
};

/// Labels keypoints with the instance id under their pixel (rounded to the nearest pixel,
/// clamped to the mask) and its class from `masks`, and marks those within
/// instanceBorderRadiusPx() of another id (Keypoint::on_instance_border); an empty mask leaves
/// them untouched.
void labelKeypoints(const cv::Mat& instance_mask, const sensors::InstanceMasks& masks,
                    std::vector<features::Keypoint>& keypoints);
/// Half-side [px] of the square around a keypoint that labelKeypoints() searches for another id:
/// 3 px, or a tenth of the described patch for coarse octaves (an ORB corner at octave 6 sits
/// anywhere within 3 px of its level-0 position).
double instanceBorderRadiusPx(const features::Keypoint& keypoint);

class FrontEnd {
 public:
  /// Without cam1 the front end is monocular: frames carry no stereo depth. Throws InputError
  /// when a learned extractor's model cannot be found.
  FrontEnd(const FrontEndOptions& options, const sensors::CameraCalibration& cam0,
           const std::optional<sensors::CameraCalibration>& cam1);

  /// Features (and stereo matches when both a right camera and image1 exist) of one bundle.
  Frame build(const sensors::FrameBundle& bundle);

  /// Masks that become known only once the left features are extracted: a segmentation running
  /// beside the extraction, or masks propagated through the new features (mask_propagation.h).
  using MasksOfFeatures =
      std::function<std::optional<sensors::InstanceMasks>(const features::FeatureSet& left)>;
  /// As build(bundle), the keypoints labelled with the masks `masks_of` returns (bundle.masks,
  /// when present, take precedence and `masks_of` is not called).
  Frame build(const sensors::FrameBundle& bundle, const MasksOfFeatures& masks_of);

  bool isStereo() const { return stereo_matcher_.has_value(); }
  /// Scale pyramid of the extractor (map points and optimisation weights use it).
  features::PyramidLayout pyramid() const { return pyramid_; }
  const features::FeatureExtractor& extractor() const { return *left_extractor_; }
  /// CPU time the helper thread of parallel extraction has used so far [ms] (0 without it).
  double helperCpuMs() const { return helper_ ? helper_->cpuMs() : 0.0; }

 private:
  /// Features of both images (the right one empty without stereo), unlabelled.
  void extract(const sensors::FrameBundle& bundle, bool stereo, Frame& frame,
               features::FeatureSet& right);
  void matchStereo(const features::FeatureSet& right, const sensors::FrameBundle& bundle,
                   const std::optional<sensors::InstanceMasks>& masks, Frame& frame) const;

  CameraModel camera0_;
  features::PyramidLayout pyramid_;
  std::unique_ptr<features::FeatureExtractor> left_extractor_, right_extractor_;
  std::optional<features::StereoMatcher> stereo_matcher_;
  /// The same without classes, for frames whose right image has no mask.
  std::optional<features::StereoMatcher> label_free_matcher_;
  std::unique_ptr<TaskThread> helper_;  ///< Extracts the right image (parallel_extraction).
};

}  // namespace superdyna::tracking

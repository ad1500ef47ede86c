#pragma once
// The front end: turns one FrameBundle (images + IMU samples) into a Frame ready for tracking —
// feature extraction on the left image and, with a right camera, stereo matching that gives
// keypoints a depth. It holds no map state, so it can run one frame ahead of tracking in its own
// thread.

#include <optional>

#include "superdyna/core/camera_model.h"
#include "superdyna/features/orb_extractor.h"
#include "superdyna/features/stereo_matcher.h"
#include "superdyna/io/calibration.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/tracking/frame.h"

namespace superdyna::tracking {

struct FrontEndOptions {
  features::OrbOptions orb;             ///< Extractor of both cameras.
  features::StereoMatchOptions stereo;  ///< Left-right matching.
  void validate() const;
};

class FrontEnd {
 public:
  /// Without cam1 the front end is monocular: frames carry no stereo depth.
  FrontEnd(const FrontEndOptions& options, const io::CameraCalibration& cam0,
           const std::optional<io::CameraCalibration>& cam1);

  /// Features (and stereo matches when both a right camera and image1 exist) of one bundle.
  Frame build(const io::FrameBundle& bundle);

  bool isStereo() const { return stereo_matcher_.has_value(); }

 private:
  void matchStereo(const features::FeatureSet& right, Frame& frame) const;

  CameraModel camera0_;
  features::OrbExtractor left_extractor_, right_extractor_;
  std::optional<features::StereoMatcher> stereo_matcher_;
};

}  // namespace superdyna::tracking

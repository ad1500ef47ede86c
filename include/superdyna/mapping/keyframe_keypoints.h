#pragma once
// Conversion of a keyframe's stored keypoint back to the feature layer's keypoint, for the
// matchers (features::) that tracking, loop closing and relocalisation run against keyframes.
// Lives in mapping because it is the lowest layer that sees both map:: and features::.

#include "superdyna/features/feature_set.h"
#include "superdyna/map/keyframe.h"

namespace superdyna::mapping {

/// The keypoint as detected: distorted pixel, octave, angle, class and instance. Stereo depth and
/// normalised coordinates stay with the keyframe.
inline features::Keypoint asFeatureKeypoint(const map::KeyFrameKeypoint& k) {
  features::Keypoint keypoint;
  keypoint.pixel = k.pixel;
  keypoint.angle = k.angle;
  keypoint.octave = k.octave;
  keypoint.class_id = k.class_id;
  keypoint.instance_id = k.instance_id;
  return keypoint;
}

}  // namespace superdyna::mapping

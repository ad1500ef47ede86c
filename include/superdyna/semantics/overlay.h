#pragma once
// A picture of the segmentation of one frame (the paper's Fig. 7b): the image in grey, each
// instance mask blended in its class colour (instances of one class in shades of it, outlined),
// and keypoints as dots coloured by their class (outlined in black).

#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "superdyna/sensors/instance_masks.h"

namespace superdyna::semantics {

struct LabelledPoint {
  cv::Point2d pixel;
  int class_id = sensors::kInstanceClassBackground;
  /// BGR colour instead of the class's (the moving-object overlay: kept green, dropped red).
  std::optional<cv::Scalar> colour;
};

/// BGR colour of a class's masks: vehicle blue, pedestrian orange, other movable violet (and
/// background green).
cv::Scalar classColour(int class_id);
/// BGR colour of a class's keypoints, bright against the masks: background green, vehicle cyan,
/// pedestrian red, other movable white.
cv::Scalar pointColour(int class_id);

/// The overlay (CV_8UC3) of `image` (CV_8UC1 or BGR) with the instance ids `ids` (CV_16UC1, same
/// size, may be empty), their classes from `masks`, and the keypoints.
cv::Mat drawOverlay(const cv::Mat& image, const cv::Mat& ids, const sensors::InstanceMasks& masks,
                    const std::vector<LabelledPoint>& points);

}  // namespace superdyna::semantics

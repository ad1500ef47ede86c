#pragma once
// Instance segmentation of one frame as every producer delivers it (a dataset's ground-truth
// masks, a segmentation network) and every consumer reads it (keypoint labelling, the
// moving-object test): a 16-bit instance id per pixel and the semantic class of each instance.
// It lives below the readers so that no stage above depends on a particular reader.

#include <Eigen/Core>
#include <map>
#include <opencv2/core.hpp>
#include <string_view>

namespace superdyna::sensors {

/// Semantic classes of instances; the ids equal features::kClassBackground / kClassVehicle /
/// kClassPedestrian / kClassOtherMovable.
inline constexpr int kInstanceClassBackground = 0;    ///< "background"
inline constexpr int kInstanceClassVehicle = 1;       ///< "vehicle"
inline constexpr int kInstanceClassPedestrian = 2;    ///< "pedestrian"
inline constexpr int kInstanceClassOtherMovable = 3;  ///< "other_movable" (animals, ...)

/// "background" | "vehicle" | "pedestrian" | "other_movable"; "unknown" for other ids.
std::string_view instanceClassName(int class_id);

/// The id of a CV_16UC1 instance-id image at a pixel position, rounded to the nearest pixel and
/// clamped to the image.
int idAtPixel(const cv::Mat& ids, const Eigen::Vector2d& pixel);

/// Instance segmentation of one (stereo) frame.
struct InstanceMasks {
  cv::Mat cam0;  ///< CV_16UC1 instance id per pixel of image0; 0 = static background.
  cv::Mat cam1;  ///< The same for image1; empty in mono.
  /// Instance id -> semantic class (kInstanceClass*) of the ids of both images.
  std::map<int, int> class_of_instance;

  /// Class of an instance id; background (0) for id 0 and ids not listed.
  int classOf(int instance_id) const;
};

}  // namespace superdyna::sensors

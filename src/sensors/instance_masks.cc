#include "superdyna/sensors/instance_masks.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace superdyna::sensors {

std::string_view instanceClassName(int class_id) {
  switch (class_id) {
    case kInstanceClassBackground:
      return "background";
    case kInstanceClassVehicle:
      return "vehicle";
    case kInstanceClassPedestrian:
      return "pedestrian";
    case kInstanceClassOtherMovable:
      return "other_movable";
    default:
      return "unknown";
  }
}

int idAtPixel(const cv::Mat& ids, const Eigen::Vector2d& pixel) {
  const int col = std::clamp(static_cast<int>(std::lround(pixel.x())), 0, ids.cols - 1);
  const int row = std::clamp(static_cast<int>(std::lround(pixel.y())), 0, ids.rows - 1);
  return ids.at<std::uint16_t>(row, col);
}

int InstanceMasks::classOf(int instance_id) const {
  const auto it = class_of_instance.find(instance_id);
  return it == class_of_instance.end() ? kInstanceClassBackground : it->second;
}

}  // namespace superdyna::sensors

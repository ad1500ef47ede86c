#include "superdyna/sensors/instance_masks.h"

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

int InstanceMasks::classOf(int instance_id) const {
  const auto it = class_of_instance.find(instance_id);
  return it == class_of_instance.end() ? kInstanceClassBackground : it->second;
}

}  // namespace superdyna::sensors

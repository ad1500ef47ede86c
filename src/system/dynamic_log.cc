#include "superdyna/system/dynamic_log.h"

#include <fmt/format.h>

#include "superdyna/core/error.h"
#include "superdyna/sensors/instance_masks.h"

namespace superdyna::system {

namespace {

/// The log's class column: the class table's name for vehicles and pedestrians, "other" for any
/// other movable class.
std::string_view className(int class_id) {
  return class_id == sensors::kInstanceClassVehicle || class_id == sensors::kInstanceClassPedestrian
             ? sensors::instanceClassName(class_id)
             : std::string_view("other");
}

}  // namespace

DynamicLog::DynamicLog(const std::filesystem::path& path, const std::string& option) : out_(path) {
  if (!out_) throw OptionError(option, "cannot open '" + path.string() + "' for writing");
  out_ << "t_ns,instance_id,class,pairs,tested,max_distance_px,threshold_px,decision,keypoints,"
          "dropped\n";
}

void DynamicLog::write(const tracking::TrackingResult& result) {
  for (const dynamic::ObjectDecision& object : result.moving.objects) {
    out_ << fmt::format("{},{},{},{},{},{:.3f},{:.3f},{},{},{}\n", result.t_ns, object.instance_id,
                        className(object.class_id), object.pairs, object.tested,
                        object.max_distance_px, object.threshold_px,
                        dynamic::toString(object.decision), object.keypoints,
                        object.dropped ? object.keypoints : 0);
  }
  out_.flush();  // a run that crashes or is stopped still leaves the rows up to its last frame
}

}  // namespace superdyna::system

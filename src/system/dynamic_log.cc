#include "superdyna/system/dynamic_log.h"

#include <fmt/format.h>

#include "superdyna/core/error.h"

namespace superdyna::system {

namespace {

const char* className(int class_id) {
  switch (class_id) {
    case features::kClassVehicle:
      return "vehicle";
    case features::kClassPedestrian:
      return "pedestrian";
    default:
      return "other";
  }
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

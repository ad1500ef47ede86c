#include "superdyna/system/frame_log.h"

#include <fmt/format.h>

#include <string>

#include "superdyna/core/error.h"

namespace superdyna::system {

namespace {

/// Distance between the predicted and the tracked position [m], millimetre resolution; empty
/// unless the frame was tracked.
std::string predictionOffset(const tracking::TrackingResult& result) {
  if (result.state != tracking::TrackingState::kTracking) return "";
  return fmt::format("{:.3f}", (result.T_w_b.t - result.T_w_predicted.t).norm());
}

}  // namespace

FrameLog::FrameLog(const std::filesystem::path& path, const std::string& option) : out_(path) {
  if (!out_) throw OptionError(option, "cannot open '" + path.string() + "' for writing");
  out_ << "frame,state,matches,inliers,prediction_m,from_reference,keyframe,recovered\n";
}

void FrameLog::write(std::size_t frame, const tracking::TrackingResult& result) {
  out_ << frame << ',' << tracking::toString(result.state) << ',' << result.matches << ','
       << result.inliers << ',' << predictionOffset(result) << ','
       << (result.from_reference ? 1 : 0) << ',' << (result.keyframe ? 1 : 0) << ','
       << (result.relocalized  ? "relocalized"
           : result.reanchored ? "imu-keyframe"
                               : "")
       << '\n';
  out_.flush();  // a run that crashes or is stopped still leaves the rows up to its last frame
}

}  // namespace superdyna::system

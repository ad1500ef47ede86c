#pragma once
// `superdyna run --frame-log FILE`: one CSV row per frame with the tracker's view of it (state,
// map matches, pose inliers, how far the tracked pose is from the predicted one, whether the pose
// came from the reference keyframe, keyframe, how the frame came back into its map after a
// failure), for finding where and why tracking failed. Header line:
//   frame,state,matches,inliers,prediction_m,from_reference,keyframe,recovered
// frame is the 0-based index in the served sequence; state is tracking::toString(); prediction_m
// is the distance between the predicted and the tracked body position [m], empty unless the state
// is tracking; recovered is "relocalized" (TrackingResult::relocalized), "imu-keyframe"
// (TrackingResult::reanchored) or empty.

#include <cstddef>
#include <filesystem>
#include <fstream>

#include "superdyna/tracking/tracker.h"

namespace superdyna::system {

class FrameLog {
 public:
  /// Creates (truncates) `path`; OptionError naming `option` when it cannot be opened.
  FrameLog(const std::filesystem::path& path, const std::string& option);
  void write(std::size_t frame, const tracking::TrackingResult& result);

 private:
  std::ofstream out_;
};

}  // namespace superdyna::system

#pragma once
// `superdyna run --dynamic-log FILE`: one CSV row per movable object per frame with the
// moving-object test's decision (dynamic/moving_object_detector.h). Header line:
//   t_ns,instance_id,class,pairs,tested,max_distance_px,threshold_px,decision,keypoints,dropped
// class: vehicle, pedestrian or other; pairs: the object's keypoints matched to the previous frame;
// tested: the pairs drawn and tested this frame; decision: moving, static or unverified (the state
// applied, after hysteresis; with dynamic.mode semantic every object is moving, untested). With
// dataset masks instance_id is the mask's id, as in the simulator's instance_states.csv.
// keypoints: the object's keypoints in the frame; dropped: how many of them tracking does not use
// (all or none) - so that `superdyna eval-dynamic` can count the features kept on static objects.

#include <filesystem>
#include <fstream>
#include <string>

#include "superdyna/tracking/tracker.h"

namespace superdyna::system {

class DynamicLog {
 public:
  /// Creates (truncates) `path`; OptionError naming `option` when it cannot be opened.
  DynamicLog(const std::filesystem::path& path, const std::string& option);
  void write(const tracking::TrackingResult& result);

 private:
  std::ofstream out_;
};

}  // namespace superdyna::system

#pragma once
// Overlays of tracked frames as the paper draws them: the left image, the instance masks and the
// keypoints by class (its Fig. 7b); with the moving-object test on (Figs. 7c and 9), every object
// it decided on in one of three styles, labelled: moving (mask filled, red outline), static (green
// outline) and unverified (dashed yellow outline, with the reason and whether its keypoints were
// dropped); the keypoints kept (green) or dropped (red) by it; and a legend in the top-left
// corner. The front end remembers a frame (System::setFrontEndCallback), its tracking result draws
// it; `superdyna run --overlay` writes them as PNG files, the ROS node publishes them.

#include <cstddef>
#include <map>
#include <mutex>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "superdyna/core/time.h"
#include "superdyna/semantics/overlay.h"
#include "superdyna/sensors/frame_bundle.h"
#include "superdyna/tracking/tracker.h"

namespace superdyna::system {

/// One drawn overlay: the frame's index in the sequence and the BGR image.
struct FrameOverlay {
  std::size_t index = 0;
  cv::Mat image;
};

/// The label of a decided object on an overlay: "moving vehicle 3", "static pedestrian 5", or
/// "unverified vehicle 7: 0 of 1 pairs to the previous frame, dropped (dynamic.drop_unverified)".
std::string describeObject(const dynamic::ObjectDecision& object,
                           const dynamic::MovingObjectOptions& options);

class FrameOverlays {
 public:
  /// Draws every `every`-th frame (>= 1); `moving_objects`: the moving-object test runs, with
  /// the options `dynamic` (the reasons of unverified objects).
  FrameOverlays(int every, bool moving_objects, dynamic::MovingObjectOptions dynamic = {})
      : every_(every), moving_objects_(moving_objects), dynamic_(std::move(dynamic)) {}

  /// Keeps what the overlay of the bundle's frame needs (thread-safe: the concurrent front end
  /// calls it from its own thread).
  void remember(const sensors::FrameBundle& bundle, const tracking::Frame& frame);
  /// The overlay of the frame of `result`, when it was remembered; forgets it.
  std::optional<FrameOverlay> draw(const tracking::TrackingResult& result);

 private:
  struct Pending {
    std::size_t index = 0;
    cv::Mat image;
    sensors::InstanceMasks masks;
    std::vector<semantics::LabelledPoint> points;
  };

  int every_;
  bool moving_objects_;
  dynamic::MovingObjectOptions dynamic_;
  std::mutex mutex_;
  std::map<TimeNs, Pending> pending_;
};

}  // namespace superdyna::system

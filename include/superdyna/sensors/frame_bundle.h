#pragma once
// One camera frame as every source serves it to the pipeline (dataset folders, bags, a live
// node): the images, the IMU samples since the previous frame, the ground truth and the instance
// masks when the source has them.

#include <cstddef>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"
#include "superdyna/sensors/instance_masks.h"
#include "superdyna/sensors/measurements.h"

namespace superdyna::sensors {

/// One frame: the left (or only) image, the right one in stereo, and what came with them.
struct FrameBundle {
  std::size_t index = 0;  ///< 0-based position in the served sequence.
  TimeNs t_ns = 0;
  cv::Mat image0;  ///< Left / only camera, CV_8UC1.
  cv::Mat image1;  ///< Right camera, CV_8UC1; empty in mono.
  /// IMU samples covering [previous frame time, t_ns]: from the last sample at or before the
  /// previous frame to the first sample at or after this one (so that integration can
  /// interpolate at both ends). For the first frame: the samples up to the first one at or
  /// after t_ns within one IMU period before it. Empty without IMU.
  std::vector<ImuSample> imu;
  std::optional<SE3d> T_w_b_gt;  ///< Ground-truth body pose at t_ns (within 1 ms), if any.
  /// Instance masks, when DatasetSourceOptions::instance_masks asked for them.
  std::optional<sensors::InstanceMasks> masks;
};

}  // namespace superdyna::sensors

#pragma once
// One IMU stream from an accelerometer and a gyroscope published apart, at different rates and
// times (RealSense D435i / T265 as OpenLORIS-Scene records them: /d400/accel/sample and
// /d400/gyro/sample). As realsense-ros's "linear_interpolation" unite method does, the output has
// one sample per gyroscope sample, with the acceleration interpolated linearly between the two
// accelerometer samples around it.

#include <cstddef>
#include <vector>

#include "superdyna/core/time.h"
#include "superdyna/sensors/measurements.h"

namespace superdyna::sensors {

struct MergedImu {
  std::vector<ImuSample> samples;
  std::size_t outside = 0;  ///< Gyroscope samples before the first or after the last accel sample.
  std::size_t in_gaps = 0;  ///< Gyroscope samples between accel samples further apart than allowed.
};

/// Merges the streams; only the `accel` of `accel` samples and the `gyro` of `gyro` samples are
/// read. Both must be in time order (InputError naming the stream and index otherwise). Gyroscope
/// samples whose bracketing accelerometer samples are more than `max_accel_gap_ns` apart are
/// dropped rather than bridged by a straight line (counted in `in_gaps`).
MergedImu mergeImuStreams(const std::vector<ImuSample>& accel, const std::vector<ImuSample>& gyro,
                          TimeNs max_accel_gap_ns = 100 * kNsPerMillisecond);

}  // namespace superdyna::sensors

#pragma once
// Sensor faults the simulator can write into a sequence, the way real sensors produce them:
//   * dropped frames: the frame's row and images are missing from both cameras' data.csv / data/
//     (a driver that lost the frame), at a rate or at listed frame indices;
//   * IMU gaps: the imu0/data.csv rows of an interval are missing (a stalled IMU stream);
//   * NaN IMU samples: the rows of an interval are written with "nan" values (a sensor glitch
//     passed through by the driver);
//   * black frames: both cameras' images of an interval are all zero (a covered or failed
//     camera; masks and ground truth are unchanged);
//   * overexposed frames: both cameras' images of an interval are saturated white (an exposure
//     far too long, a camera facing the sun);
//   * a missing camera: cam1's rows and images of an interval are not written (one camera's
//     driver dropped out; cam0 goes on);
//   * a camera-IMU time offset: every IMU timestamp is written `imu_time_offset_s` late (the IMU
//     clock runs ahead of the cameras' and the ground truth's), which no reader can detect;
//   * repeated timestamps: the camera and IMU rows of an interval are each written twice (a
//     driver publishing a message again);
//   * out-of-order timestamps: in an interval, each two consecutive camera rows and IMU rows are
//     written swapped (messages arriving late);
//   * saturated IMU samples: the rows of an interval are written at the sensor's range on every
//     axis, with the true values' signs (readings clipped by a shock).
// Intervals are in seconds after the first frame of the sequence, half-open [t0, t1).

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "superdyna/core/time.h"

namespace superdyna::sim {

/// [t0_s, t1_s) in seconds after the first frame.
struct FaultInterval {
  double t0_s = 0.0;
  double t1_s = 0.0;
  bool contains(double t_s) const { return t_s >= t0_s && t_s < t1_s; }
};

/// Parses "T0:T1" (seconds, 0 <= T0 < T1); OptionError naming `option` otherwise.
FaultInterval parseFaultInterval(const std::string& text, const std::string& option);

struct SensorFaultOptions {
  double drop_frame_rate = 0.0;             ///< Probability that a frame is dropped, [0, 1).
  std::vector<std::size_t> drop_frames;     ///< Frame indices (0-based, > 0) that are dropped.
  std::vector<FaultInterval> imu_gaps;      ///< IMU rows left out.
  std::vector<FaultInterval> imu_nan;       ///< IMU rows written as NaN.
  std::vector<FaultInterval> black_frames;  ///< Images written all black.
  std::vector<FaultInterval> overexposed_frames;  ///< Images written all white (255).
  std::vector<FaultInterval> missing_cam1;        ///< cam1 rows and images left out.
  std::vector<FaultInterval> repeated_rows;       ///< Camera and IMU rows written twice.
  std::vector<FaultInterval> swapped_rows;        ///< Consecutive rows written swapped.
  std::vector<FaultInterval> imu_saturated;       ///< IMU rows written at the sensor's range.
  double imu_time_offset_s = 0.0;  ///< Added to every IMU timestamp [s], |offset| < 1.

  bool any() const;
  /// Throws OptionError naming the option of the first invalid value.
  void validate() const;
  /// Whether frame `index` is dropped: listed, or drawn at drop_frame_rate from `seed` (a pure
  /// function of seed and index). The first frame is never dropped (intervals start at it).
  bool dropsFrame(std::size_t index, std::uint64_t seed) const;
};

/// Parses --drop-frames: a rate in [0, 1) ("0.05") or a comma-separated list of frame indices
/// ("10,11,40"); OptionError naming --drop-frames otherwise.
void parseDropFrames(const std::string& text, SensorFaultOptions* faults);

/// Whether t_s lies in one of the intervals.
bool inAnyInterval(const std::vector<FaultInterval>& intervals, double t_s);

/// A data.csv row to be written, at t_s after the first frame.
struct TimedRow {
  double t_s = 0.0;
  std::string text;
};

/// The rows as the faults write them: each row in a repeated_rows interval twice, and in the
/// swapped_rows intervals each two consecutive rows (both inside) in reverse order.
std::vector<std::string> faultyRowOrder(const std::vector<TimedRow>& rows,
                                        const SensorFaultOptions& faults);

}  // namespace superdyna::sim

#pragma once
// Reading and writing trajectories in the formats the SLAM literature uses:
//  - TUM:   "t tx ty tz qx qy qz qw", t in seconds; '#' comments; header lines before the data
//           (OpenLORIS files start with "scene: ...", "frame: ...") are skipped. OpenLORIS
//           ground-truth files hold several recordings, each after a "seq: N" line; all are
//           read (their times increase), or one is chosen with `segment`.
//  - EuRoC: CSV "t_ns, px, py, pz, qw, qx, qy, qz[, ...]" (ground-truth files have 17 columns:
//           + velocity, gyro bias, accel bias; only the pose is used here).
//  - KITTI: 12 numbers a line, the row-major 3x4 matrix [R | t]; no timestamps in the file, they
//           come from a separate times file (one time in seconds a line) or default to 10 Hz.

#include <filesystem>
#include <optional>
#include <string>

#include "superdyna/core/trajectory.h"

namespace superdyna::io {

enum class TrajectoryFormat { kAuto, kTum, kEuroc, kKitti };

/// "auto", "tum", "euroc", "kitti" -> format; throws OptionError otherwise.
TrajectoryFormat parseTrajectoryFormat(const std::string& name);
std::string toString(TrajectoryFormat format);

/// Looks at the first data line: commas -> EuRoC, 12 fields -> KITTI, 8 fields -> TUM.
/// Throws InputError naming the file when nothing fits.
TrajectoryFormat detectTrajectoryFormat(const std::filesystem::path& file);

struct TrajectoryReadOptions {
  TrajectoryFormat format = TrajectoryFormat::kAuto;
  /// KITTI only: file with one timestamp (seconds) per pose. Without it, pose i gets i * 0.1 s.
  std::optional<std::filesystem::path> kitti_times;
  /// TUM only: read just the rows after the line "seq: N" (OpenLORIS multi-recording files).
  std::optional<int> segment;
  /// TUM only: the first column is in nanoseconds, not seconds (ORB-SLAM3 writes its EuRoC
  /// trajectories so, e.g. "1403636579763555584.000000"; rounded to the nearest nanosecond).
  bool tum_time_in_ns = false;
};

/// Reads and validates a trajectory: every row well-formed and finite, quaternions of unit norm
/// (within 1e-2, then normalised), rotation matrices orthonormal (within 1e-3), timestamps
/// strictly increasing. Errors name the file and line.
Trajectory readTrajectory(const std::filesystem::path& file, const TrajectoryReadOptions& options);
Trajectory readTrajectory(const std::filesystem::path& file);

/// Reads a KITTI times file (one time in seconds a line, strictly increasing).
std::vector<TimeNs> readTimesFile(const std::filesystem::path& file);

/// Writes `trajectory` in `format` (not kAuto). TUM times are written with nine decimals so that
/// nanosecond timestamps round-trip exactly. Throws InputError if the file cannot be written.
void writeTrajectory(const std::filesystem::path& file, const Trajectory& trajectory,
                     TrajectoryFormat format);

}  // namespace superdyna::io

#pragma once
// Where the simulated body motion comes from: a real trajectory file (EuRoC / TUM-VI IMU poses,
// OpenLORIS robot base poses, KITTI camera poses) or a procedural flight. Each source's tracked
// frame has its own axes; the motion convention turns it into the body (IMU) frame of a
// EuRoC-like rig, whose cameras look along the body z axis with image "up" along body x, in a
// z-up world with gravity along -z. The rig's camera then looks where the source's camera did
// (up to the source's small camera-IMU misalignment and offset).

#include <filesystem>
#include <optional>
#include <string>

#include "superdyna/core/trajectory.h"
#include "superdyna/io/trajectory_io.h"

namespace superdyna::sim {

enum class MotionConvention {
  kAuto,      ///< KITTI poses -> kCamera; files with a "frame: base_link" line -> kForwardX;
              ///< otherwise kTumVi when the tracked frame's z axis points up on average (of its
              ///< three axes the closest to the world's +z), else kBody.
  kBody,      ///< The file tracks a EuRoC-like IMU body in a z-up world: used as is (EuRoC's
              ///< IMU has x up, the cameras look along z).
  kTumVi,     ///< A TUM-VI IMU in a z-up world: z up, the cameras look along -y, image right
              ///< along -x (TUM-VI's cam0 T_cam_imu, to within 3 degrees).
  kForwardX,  ///< A vehicle/robot frame, x forward, z up (OpenLORIS base_link): camera looks
              ///< forward, mounted `mount_height_m` above the tracked frame.
  kCamera,    ///< A camera frame, x right, y down, z forward, in a y-down world (KITTI).
};

/// auto|body|tum-vi|forward-x|camera
MotionConvention parseMotionConvention(const std::string& name);
std::string toString(MotionConvention convention);

struct MotionSourceOptions {
  std::optional<std::filesystem::path> trajectory_file;  ///< None: procedural flight.
  io::TrajectoryReadOptions read;                        ///< Format, KITTI times, segment.
  MotionConvention convention = MotionConvention::kAuto;
  double mount_height_m = 1.2;  ///< kForwardX: camera height above the tracked frame [m].
  double start_s = 0.0;         ///< Skip this much of the source's beginning [s], >= 0.
  double duration_s = 60.0;     ///< Length of the sequence [s], > 0.
};

/// Body poses T_w_b over [start, start + duration] of the source (plus a margin of up to 1 s on
/// each side where the source has it, so a spline fitted to them covers the whole window).
/// Procedural motion is scaled to the scene's size by `procedural_extent_m` (half-width of the
/// flight along x). Throws InputError when the file is shorter than the requested window.
struct MotionWindow {
  Trajectory body_poses;       ///< T_w_b samples.
  TimeRange window;            ///< The requested sequence time range.
  TimeNs start_origin_ns = 0;  ///< The trajectory time that --start (start_s) counts from.
  MotionConvention convention = MotionConvention::kBody;  ///< As resolved from kAuto.
};

MotionWindow loadMotion(const MotionSourceOptions& options, double procedural_extent_m);

}  // namespace superdyna::sim

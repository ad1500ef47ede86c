#include "superdyna/sim/motion_source.h"

#include <fmt/format.h>

#include <fstream>

#include "superdyna/core/error.h"
#include "superdyna/sim/procedural_trajectory.h"

namespace superdyna::sim {

namespace fs = std::filesystem;

namespace {

constexpr TimeNs kMarginNs = kNsPerSecond;

/// Whether the first lines of a TUM file declare a robot base frame (OpenLORIS header).
bool declaresBaseLinkFrame(const fs::path& file) {
  std::ifstream in(file);
  std::string line;
  for (int i = 0; i < 10 && std::getline(in, line); ++i) {
    if (line.rfind("frame:", 0) == 0 && line.find("base_link") != std::string::npos) return true;
  }
  return false;
}

/// Whether the tracked frame's z axis is, on average over the trajectory, the one of its axes
/// closest to the world's up (+z): a TUM-VI IMU held upright, where a EuRoC IMU has x up.
bool trackedFrameHasZUp(const Trajectory& source) {
  Eigen::Vector3d up_in_tracked = Eigen::Vector3d::Zero();
  for (const StampedPose& pose : source)
    up_in_tracked += pose.T_w_x.rotation().row(2).transpose();  // R^T * world z
  Eigen::Index axis = 0;
  up_in_tracked.maxCoeff(&axis);
  return axis == 2;
}

MotionConvention resolveConvention(const MotionSourceOptions& options, const Trajectory& source) {
  if (options.convention != MotionConvention::kAuto) return options.convention;
  if (!options.trajectory_file) return MotionConvention::kForwardX;  // procedural: x forward
  const auto format = options.read.format == io::TrajectoryFormat::kAuto
                          ? io::detectTrajectoryFormat(*options.trajectory_file)
                          : options.read.format;
  if (format == io::TrajectoryFormat::kKitti) return MotionConvention::kCamera;
  if (declaresBaseLinkFrame(*options.trajectory_file)) return MotionConvention::kForwardX;
  return trackedFrameHasZUp(source) ? MotionConvention::kTumVi : MotionConvention::kBody;
}

/// Body axes expressed in the tracked frame: the camera (z forward, y down) must look along the
/// tracked frame's forward axis, so body z = forward and body x = up.
SE3d bodyInTrackedFrame(MotionConvention convention, double mount_height_m) {
  Eigen::Matrix3d R;
  switch (convention) {
    case MotionConvention::kForwardX:  // forward x, left y, up z
      R.col(0) = Eigen::Vector3d::UnitZ();
      R.col(1) = -Eigen::Vector3d::UnitY();
      R.col(2) = Eigen::Vector3d::UnitX();
      return SE3d(R, Eigen::Vector3d(0.0, 0.0, mount_height_m));
    case MotionConvention::kCamera:  // right x, down y, forward z
      R.col(0) = -Eigen::Vector3d::UnitY();
      R.col(1) = Eigen::Vector3d::UnitX();
      R.col(2) = Eigen::Vector3d::UnitZ();
      return SE3d(R, Eigen::Vector3d::Zero());
    case MotionConvention::kTumVi:  // TUM-VI IMU: right -x, forward -y, up z
      R.col(0) = Eigen::Vector3d::UnitZ();
      R.col(1) = -Eigen::Vector3d::UnitX();
      R.col(2) = -Eigen::Vector3d::UnitY();
      return SE3d(R, Eigen::Vector3d::Zero());
    case MotionConvention::kBody:
    case MotionConvention::kAuto:
      break;
  }
  return SE3d();
}

/// World rotation to z-up: KITTI's world is its first camera frame (y down, z forward).
SE3d zUpWorldFromSource(MotionConvention convention) {
  if (convention != MotionConvention::kCamera) return SE3d();
  Eigen::Matrix3d R;
  R << 0, 0, 1,  //
      -1, 0, 0,  //
      0, -1, 0;
  return SE3d(R, Eigen::Vector3d::Zero());
}

/// Why --start and --duration do not fit a trajectory of `covered_s` seconds, and what range does.
std::string windowMisfit(double covered_s, const MotionSourceOptions& options) {
  const std::string asked = fmt::format(
      "the trajectory covers {:.2f} s; --start {:.2f} s + --duration {:.2f} s ends {:.2f} s "
      "after its end",
      covered_s, options.start_s, options.duration_s,
      options.start_s + options.duration_s - covered_s);
  if (options.start_s >= covered_s) {
    return fmt::format("{}: --start must be below {:.2f} s", asked, covered_s);
  }
  return fmt::format(
      "{}: --start + --duration must be at most {:.2f} s (with --start {:.2f} s, --duration up "
      "to {:.2f} s)",
      asked, covered_s, options.start_s, covered_s - options.start_s);
}

Trajectory proceduralSource(double extent_m, double duration_s) {
  LissajousOptions options;
  options.duration_s = duration_s + 2.0 * nsToSeconds(kMarginNs);
  options.rate_hz = 100.0;
  options.ax_m = extent_m;
  options.ay_m = 0.6 * extent_m;
  options.az_m = std::min(0.3, 0.05 * extent_m);
  options.height_m = 0.0;
  options.period_s = std::max(30.0, 2.4 * extent_m);  // walking to slow-driving speeds
  options.tilt_rad = 0.03;
  return makeLissajousTrajectory(options);
}

}  // namespace

MotionConvention parseMotionConvention(const std::string& name) {
  if (name == "auto") return MotionConvention::kAuto;
  if (name == "body") return MotionConvention::kBody;
  if (name == "forward-x") return MotionConvention::kForwardX;
  if (name == "camera") return MotionConvention::kCamera;
  if (name == "tum-vi") return MotionConvention::kTumVi;
  throw OptionError(
      "motion-convention",
      fmt::format("unknown convention '{}' (auto|body|tum-vi|forward-x|camera)", name));
}

std::string toString(MotionConvention convention) {
  switch (convention) {
    case MotionConvention::kAuto:
      return "auto";
    case MotionConvention::kBody:
      return "body";
    case MotionConvention::kForwardX:
      return "forward-x";
    case MotionConvention::kCamera:
      return "camera";
    case MotionConvention::kTumVi:
      return "tum-vi";
  }
  return "unknown";
}

MotionWindow loadMotion(const MotionSourceOptions& options, double procedural_extent_m) {
  if (!(options.duration_s > 0.0)) throw OptionError("duration", "must be > 0");
  if (options.start_s < 0.0) throw OptionError("start", "must be >= 0");
  MotionWindow result;
  // The procedural flight goes on for ever: it is generated as far as the window needs.
  const Trajectory source =
      options.trajectory_file
          ? io::readTrajectory(*options.trajectory_file, options.read)
          : proceduralSource(procedural_extent_m, options.start_s + options.duration_s);
  result.convention = resolveConvention(options, source);
  const TimeNs source_begin = source.front().t_ns + (options.trajectory_file ? 0 : kMarginNs);
  result.start_origin_ns = source_begin;
  result.window.begin = source_begin + secondsToNs(options.start_s);
  result.window.end = result.window.begin + secondsToNs(options.duration_s);
  if (result.window.end > source.back().t_ns) {
    const fs::path name = options.trajectory_file ? *options.trajectory_file : "procedural";
    throw InputError(InputLocation(name),
                     windowMisfit(nsToSeconds(source.back().t_ns - source_begin), options));
  }
  const SE3d T_w_src0 = zUpWorldFromSource(result.convention);
  const SE3d T_src_b = bodyInTrackedFrame(result.convention, options.mount_height_m);
  for (const StampedPose& pose : source) {
    if (pose.t_ns < result.window.begin - kMarginNs || pose.t_ns > result.window.end + kMarginNs) {
      continue;
    }
    result.body_poses.push_back({pose.t_ns, T_w_src0 * pose.T_w_x * T_src_b});
  }
  return result;
}

}  // namespace superdyna::sim

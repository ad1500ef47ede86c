#include "superdyna/system/system.h"

#include "superdyna/core/error.h"
#include "superdyna/mapping/map_inertial_alignment.h"

namespace superdyna::system {

SensorMode parseSensorMode(const std::string& name) {
  if (name == "stereo") return SensorMode::kStereo;
  if (name == "stereo-inertial") return SensorMode::kStereoInertial;
  if (name == "mono") return SensorMode::kMono;
  if (name == "mono-inertial") return SensorMode::kMonoInertial;
  throw OptionError("--mode", "unknown mode '" + name +
                                  "'; supported modes: stereo, stereo-inertial, mono, "
                                  "mono-inertial");
}

std::string toString(SensorMode mode) {
  switch (mode) {
    case SensorMode::kStereo:
      return "stereo";
    case SensorMode::kStereoInertial:
      return "stereo-inertial";
    case SensorMode::kMono:
      return "mono";
    case SensorMode::kMonoInertial:
      return "mono-inertial";
  }
  return "?";
}

bool usesImu(SensorMode mode) {
  return mode == SensorMode::kStereoInertial || mode == SensorMode::kMonoInertial;
}

bool isMonocular(SensorMode mode) {
  return mode == SensorMode::kMono || mode == SensorMode::kMonoInertial;
}

void SystemOptions::validate() const {
  front_end.validate();
  tracker.validate();
  mapping.validate();
}

namespace {

SystemOptions checkedOptions(SystemOptions options) {
  options.tracker.use_imu = usesImu(options.mode);
  // Triangulation between keyframes is the only source of new points of a monocular map.
  if (isMonocular(options.mode)) options.mapping.triangulate = true;
  options.validate();
  return options;
}

}  // namespace

System::System(const SystemOptions& options, const io::CameraCalibration& cam0,
               const std::optional<io::CameraCalibration>& cam1,
               const std::optional<io::ImuCalibration>& imu)
    : options_(checkedOptions(options)),
      front_end_(options_.front_end, cam0, isMonocular(options_.mode) ? std::nullopt : cam1),
      tracker_(
          options_.tracker,
          tracking::PyramidInfo{options_.front_end.orb.scale_factor, options_.front_end.orb.levels},
          options_.mapping, cam0, isMonocular(options_.mode) ? std::nullopt : cam1,
          usesImu(options_.mode) ? imu : std::nullopt) {
  if (usesImu(options_.mode) && !imu) {
    throw OptionError("--mode", toString(options_.mode) + " needs IMU calibration and samples");
  }
  if (!isMonocular(options_.mode) && !cam1) {
    throw OptionError("--mode", toString(options_.mode) + " needs a second camera");
  }
}

tracking::TrackingResult System::process(const io::FrameBundle& bundle) {
  const tracking::TrackingResult result = tracker_.track(front_end_.build(bundle));
  if (result.world_change) {
    for (std::size_t i = map_start_; i < trajectory_.size(); ++i) {
      trajectory_[i].T_w_x =
          mapping::transformBodyPose(*result.world_change, trajectory_[i].T_w_x, tracker_.T_b_c0());
    }
  }
  if (result.state == tracking::TrackingState::kInitialized) map_start_ = trajectory_.size();
  if (result.state == tracking::TrackingState::kInitializing) {
    ++initializing_frames_;
  } else {
    trajectory_.push_back({bundle.t_ns, result.T_w_b});
  }
  ++timings_.frames;
  if (result.keyframe) ++timings_.keyframes;
  timings_.total.extract_ms += result.times.extract_ms;
  timings_.total.stereo_ms += result.times.stereo_ms;
  timings_.total.track_ms += result.times.track_ms;
  timings_.total.local_ba_ms += result.times.local_ba_ms;
  if (result.state == tracking::TrackingState::kLost) ++lost_frames_;
  return result;
}

}  // namespace superdyna::system

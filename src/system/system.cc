#include "superdyna/system/system.h"

#include "superdyna/core/error.h"

namespace superdyna::system {

SensorMode parseSensorMode(const std::string& name) {
  if (name == "stereo") return SensorMode::kStereo;
  if (name == "stereo-inertial") return SensorMode::kStereoInertial;
  if (name == "mono" || name == "mono-inertial") {
    throw OptionError("--mode", "'" + name +
                                    "' is not implemented yet; supported modes: stereo, "
                                    "stereo-inertial");
  }
  throw OptionError("--mode",
                    "unknown mode '" + name + "'; supported modes: stereo, stereo-inertial");
}

std::string toString(SensorMode mode) {
  return mode == SensorMode::kStereo ? "stereo" : "stereo-inertial";
}

bool usesImu(SensorMode mode) {
  return mode == SensorMode::kStereoInertial;
}

void SystemOptions::validate() const {
  front_end.validate();
  tracker.validate();
  mapping.validate();
}

namespace {

SystemOptions checkedOptions(SystemOptions options) {
  options.tracker.use_imu = usesImu(options.mode);
  options.tracker.projection.same_class_only = options.front_end.features.class_wise_matching;
  options.validate();
  return options;
}

}  // namespace

System::System(const SystemOptions& options, const io::CameraCalibration& cam0,
               const std::optional<io::CameraCalibration>& cam1,
               const std::optional<io::ImuCalibration>& imu)
    : options_(checkedOptions(options)),
      front_end_(options_.front_end, cam0, cam1),
      tracker_(
          options_.tracker,
          tracking::PyramidInfo{front_end_.pyramid().scale_factor, front_end_.pyramid().levels},
          options_.mapping, cam0, cam1, usesImu(options_.mode) ? imu : std::nullopt) {
  if (usesImu(options_.mode) && !imu) {
    throw OptionError("--mode", "stereo-inertial needs IMU calibration and samples");
  }
}

tracking::TrackingResult System::process(const io::FrameBundle& bundle) {
  const tracking::Frame frame = front_end_.build(bundle);
  const tracking::TrackingResult result = tracker_.track(frame);
  timings_.matches.stereo += frame.numStereo();
  timings_.matches.stereo_cross_class += frame.cross_class_stereo;
  timings_.matches.map += result.matches;
  timings_.matches.map_cross_class += result.cross_class_matches;
  trajectory_.push_back({bundle.t_ns, result.T_w_b});
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

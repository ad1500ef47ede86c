#pragma once
// The SLAM system facade: feeds FrameBundles through tracking and local mapping (sequentially, so
// the same input gives a bit-identical trajectory) and records the body trajectory of every frame
// and per-stage timings.

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>

#include "superdyna/core/trajectory.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/mapping/local_mapper.h"
#include "superdyna/tracking/front_end.h"
#include "superdyna/tracking/tracker.h"

namespace superdyna::system {

enum class SensorMode { kStereo, kStereoInertial };

/// "stereo" | "stereo-inertial"; "mono" / "mono-inertial" throw OptionError (not implemented yet).
SensorMode parseSensorMode(const std::string& name);
std::string toString(SensorMode mode);
bool usesImu(SensorMode mode);

struct SystemOptions {
  SensorMode mode = SensorMode::kStereo;
  tracking::FrontEndOptions front_end;
  tracking::TrackerOptions tracker;
  mapping::LocalMapperOptions mapping;
  bool deterministic = true;  ///< Sequential, single-threaded solvers (the only mode so far).
  void validate() const;
};

/// Reads a YAML options file (sections `features`, `orb`, `stereo`, `projection`, `pose`,
/// `tracker`, `mapping`) over `defaults`; an unknown section or key is an InputError naming file
/// and key.
SystemOptions loadSystemOptions(const std::filesystem::path& file, SystemOptions defaults = {});

/// Match counts summed over the processed frames. Cross-class matches pair keypoints (or a map
/// point and a keypoint) of different semantic classes; class-wise matching makes them 0.
struct MatchCounts {
  long stereo = 0;              ///< Left keypoints with a stereo partner.
  long stereo_cross_class = 0;  ///< ... whose partner has another class_id.
  long map = 0;                 ///< Map-to-frame matches (before pose-outlier rejection).
  long map_cross_class = 0;     ///< ... between a map point and a keypoint of other classes.
};

/// Sums of the per-stage times over the processed frames [ms], and match counts.
struct TimingSummary {
  std::size_t frames = 0;
  std::size_t keyframes = 0;
  tracking::StageTimes total;
  MatchCounts matches;
  double meanMs(double total_ms) const { return frames > 0 ? total_ms / frames : 0.0; }
};

class System {
 public:
  System(const SystemOptions& options, const io::CameraCalibration& cam0,
         const std::optional<io::CameraCalibration>& cam1,
         const std::optional<io::ImuCalibration>& imu);

  tracking::TrackingResult process(const io::FrameBundle& bundle);

  const Trajectory& trajectory() const { return trajectory_; }
  const TimingSummary& timings() const { return timings_; }
  std::size_t lostFrames() const { return lost_frames_; }
  int resets() const { return tracker_.resets(); }
  std::size_t numKeyFrames() const { return tracker_.map().numKeyFrames(); }
  std::size_t numMapPoints() const { return tracker_.map().numMapPoints(); }

 private:
  SystemOptions options_;
  tracking::FrontEnd front_end_;
  tracking::Tracker tracker_;
  Trajectory trajectory_;
  TimingSummary timings_;
  std::size_t lost_frames_ = 0;
};

}  // namespace superdyna::system

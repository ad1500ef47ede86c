#pragma once
// A dataset as the SLAM pipeline consumes it: one sensors::FrameBundle per camera frame, with the
// images loaded and checked, the IMU samples that cover the interval since the previous frame, and
// the ground truth at the frame time when the dataset has it. EuRoC (stereo/mono, with or without
// IMU) and KITTI odometry (stereo/mono, no IMU) folders are supported.

#include <cstddef>
#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "superdyna/io/calibration.h"
#include "superdyna/io/euroc_dataset.h"
#include "superdyna/sensors/frame_bundle.h"
#include "superdyna/sensors/instance_masks.h"

namespace superdyna::io {

enum class DatasetKind { kEuroc, kKitti };
DatasetKind parseDatasetKind(const std::string& name);  ///< "euroc" | "kitti"

struct DatasetSourceOptions {
  bool stereo = true;           ///< Serve the second camera (error if the dataset has none).
  bool inertial = true;         ///< Serve IMU samples (error if the dataset has none).
  std::size_t first_frame = 0;  ///< Skip this many frames (of those the IMU covers).
  std::size_t max_frames = 0;   ///< Serve at most this many (0 = all).
  /// Serve the per-camera instance masks (EuRoC layout written by the simulator: camN/mask/ and
  /// instances.csv); InputError at open when the dataset has none.
  bool instance_masks = false;
};

/// Frames in time order. Throws InputError (from the readers, or on a missing stream) at open.
class DatasetSource {
 public:
  virtual ~DatasetSource() = default;

  /// The next frame, or nullopt at the end. Image problems throw InputError naming the file.
  virtual std::optional<sensors::FrameBundle> next() = 0;
  /// Number of frames this source serves in total.
  virtual std::size_t size() const = 0;

  virtual const sensors::CameraCalibration& camera0() const = 0;
  /// Second camera's calibration; nullopt in mono.
  virtual const std::optional<sensors::CameraCalibration>& camera1() const = 0;
  /// IMU calibration; nullopt without IMU.
  virtual const std::optional<sensors::ImuCalibration>& imu() const = 0;
  /// Ground truth of the served time range (body frame; KITTI: left camera), may be empty.
  virtual Trajectory groundTruth() const = 0;
  /// Non-fatal findings of the readers.
  virtual const std::vector<std::string>& warnings() const = 0;
};

/// IMU samples from the last one at or before t0 to the first one at or after t1 (samples in time
/// order): what a frame at t1 after a frame at t0 integrates, interpolating at both ends.
std::vector<sensors::ImuSample> bracketingImu(const std::vector<sensors::ImuSample>& imu, TimeNs t0,
                                              TimeNs t1);

std::unique_ptr<DatasetSource> openDataset(DatasetKind kind, const std::filesystem::path& path,
                                           const DatasetSourceOptions& options);

}  // namespace superdyna::io

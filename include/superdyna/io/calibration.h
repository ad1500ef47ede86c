#pragma once
// Camera and IMU calibration (sensors/calibration.h) read from EuRoC/Kalibr-style sensor.yaml
// files, and the image side of a calibration: references to image files and loading them checked
// against the calibration.
//
// Frames: B is the body frame (on EuRoC the IMU frame), C a camera, I the IMU. T_b_c is the pose
// of the camera in the body frame (p_b = T_b_c * p_c), which is what EuRoC calls T_BS of a sensor.

#include <filesystem>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "superdyna/core/camera_model.h"
#include "superdyna/core/error.h"
#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"
#include "superdyna/sensors/calibration.h"

namespace superdyna::io {

/// "pinhole" -> kPinhole; throws InputError naming `where` otherwise.
sensors::ProjectionModel parseProjectionModel(std::string_view name, const InputLocation& where);
/// "radial-tangential" | "radtan" | "plumb_bob" | "equidistant" | "fisheye" | "none"; throws
/// InputError naming `where` otherwise.
DistortionModel parseDistortionModel(std::string_view name, const InputLocation& where);

/// Reads a camera sensor.yaml (EuRoC): T_BS, rate_hz, resolution, camera_model, intrinsics
/// [fx, fy, cx, cy], distortion_model, distortion_coefficients. `name` is the parent folder's.
/// Every missing or invalid field throws InputError naming the file, the field and, where known,
/// the line; values are validated (positive resolution, focal lengths and rate; coefficient count
/// matching the model; T_BS a rigid transform).
sensors::CameraCalibration readCameraCalibration(const std::filesystem::path& sensor_yaml);

/// Reads an IMU sensor.yaml (EuRoC): T_BS, rate_hz and the four positive noise parameters; the
/// optional positive `gyroscope_range` and `accelerometer_range` (the simulator writes them).
sensors::ImuCalibration readImuCalibration(const std::filesystem::path& sensor_yaml);

/// The sensors of a rig as a folder of sensor.yaml files describes them.
struct SensorRig {
  sensors::CameraCalibration camera0;
  std::optional<sensors::CameraCalibration> camera1;  ///< When asked for (stereo).
  std::optional<sensors::ImuCalibration> imu;         ///< When asked for (inertial).
};

/// Reads cam0/sensor.yaml, and cam1/sensor.yaml when `stereo`, imu0/sensor.yaml when `inertial`,
/// from `folder` or its mav0/ (an EuRoC sequence folder or its mav0): the calibration of sensors
/// whose data come from elsewhere (a bag, a live node). InputError naming the folder when it has
/// no cam0/sensor.yaml, or the file.
SensorRig readSensorFolder(const std::filesystem::path& folder, bool stereo, bool inertial);

/// Checks a homogeneous 4x4 transform: finite, last row 0 0 0 1, rotation orthonormal within
/// kRotationOrthonormalityTolerance; returns it re-orthonormalised. Throws InputError at `where`.
SE3d checkedRigidTransform(const Eigen::Matrix4d& M, const InputLocation& where);

/// Checks the values of a calibration built in code or from another format (positive size, focal
/// lengths and rate; coefficient count matching the model). Throws InputError at `where`.
void validateCameraCalibration(const sensors::CameraCalibration& calibration,
                               const InputLocation& where);

/// An image file of a camera stream.
struct ImageRef {
  TimeNs t_ns = 0;             ///< Exposure timestamp.
  std::filesystem::path path;  ///< Image file, under the folder given to the reader.
};

/// A synchronised stereo pair: both images share the timestamp.
struct StereoFrameRef {
  TimeNs t_ns = 0;
  std::filesystem::path cam0;  ///< Left image.
  std::filesystem::path cam1;  ///< Right image.
};

/// Loads an image as 8-bit grayscale (CV_8UC1; colour images are converted). Throws InputError
/// naming the file when it is missing, unreadable or not an image, or when its size differs from
/// the calibrated resolution ("... is 640x480, expected 752x480").
cv::Mat loadImage(const std::filesystem::path& file, const sensors::CameraCalibration& calibration);

/// Decodes a PNG file (instance masks, segmentation images) with cv::imread's `flags`. Only PNG is
/// decoded: OpenCV would try every decoder whose signature matches, and some abort the process on
/// damaged input (GDCM's DICOM reader asserts). Throws InputError naming the file when it cannot
/// be read, is not a PNG file or cannot be decoded.
cv::Mat decodePngFile(const std::filesystem::path& file, int flags);

}  // namespace superdyna::io

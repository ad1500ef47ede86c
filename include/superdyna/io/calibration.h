#pragma once
// Camera and IMU calibration, read from EuRoC/Kalibr-style sensor.yaml files, and the image side
// of a calibration: references to image files and loading them checked against the calibration.
//
// Frames: B is the body frame (on EuRoC the IMU frame), C a camera, I the IMU. T_b_c is the pose
// of the camera in the body frame (p_b = T_b_c * p_c), which is what EuRoC calls T_BS of a sensor.

#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "superdyna/core/camera_model.h"
#include "superdyna/core/error.h"
#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"

namespace superdyna::io {

/// Projection model of a camera (the distortion model is superdyna::DistortionModel).
enum class ProjectionModel { kPinhole };

/// "pinhole" -> kPinhole; throws InputError naming `where` otherwise.
ProjectionModel parseProjectionModel(std::string_view name, const InputLocation& where);
/// "radial-tangential" | "radtan" | "plumb_bob" | "equidistant" | "fisheye" | "none"; throws
/// InputError naming `where` otherwise.
DistortionModel parseDistortionModel(std::string_view name, const InputLocation& where);
std::string toString(ProjectionModel model);

/// Intrinsic and extrinsic calibration of one camera.
struct CameraCalibration {
  std::string name;      ///< Sensor name, e.g. "cam0" (the folder of its sensor.yaml).
  SE3d T_b_c;            ///< Pose of the camera in the body frame (EuRoC T_BS).
  int width = 0;         ///< Image width in pixels.
  int height = 0;        ///< Image height in pixels.
  double rate_hz = 0.0;  ///< Nominal frame rate.
  ProjectionModel model = ProjectionModel::kPinhole;
  double fx = 0.0;  ///< Focal length along x, pixels.
  double fy = 0.0;  ///< Focal length along y, pixels.
  double cx = 0.0;  ///< Principal point x, pixels.
  double cy = 0.0;  ///< Principal point y, pixels.
  DistortionModel distortion_model = DistortionModel::kNone;
  /// kRadialTangential: k1 k2 p1 p2 [k3]; kEquidistant: k1 k2 k3 k4; kNone: empty.
  std::vector<double> distortion;

  /// The 3x3 CV_64F camera matrix [fx 0 cx; 0 fy cy; 0 0 1].
  cv::Mat cameraMatrix() const;
  /// Distortion coefficients as a 1xN CV_64F row in OpenCV's order (cv::undistort for
  /// radial-tangential, cv::fisheye for equidistant); 1x4 zeros for kNone.
  cv::Mat distortionCoefficients() const;
  cv::Size imageSize() const { return {width, height}; }
  /// The projection/unprojection model of this calibration.
  CameraModel cameraModel() const;
};

/// IMU calibration: extrinsics and the continuous-time noise model (Kalibr/EuRoC convention).
struct ImuCalibration {
  SE3d T_b_i;                                ///< Pose of the IMU in the body frame (EuRoC T_BS).
  double rate_hz = 0.0;                      ///< Nominal sample rate.
  double gyroscope_noise_density = 0.0;      ///< White noise, rad / s / sqrt(Hz).
  double gyroscope_random_walk = 0.0;        ///< Bias random walk, rad / s^2 / sqrt(Hz).
  double accelerometer_noise_density = 0.0;  ///< White noise, m / s^2 / sqrt(Hz).
  double accelerometer_random_walk = 0.0;    ///< Bias random walk, m / s^3 / sqrt(Hz).
  /// Measurement ranges (optional sensor.yaml keys `gyroscope_range` [rad/s] and
  /// `accelerometer_range` [m/s^2]; 0 = unknown): readings at or beyond them are clipped ones.
  double gyroscope_range = 0.0;
  double accelerometer_range = 0.0;

  /// Nominal time between samples (rate_hz must be positive, as the readers ensure).
  TimeNs periodNs() const { return secondsToNs(1.0 / rate_hz); }
};

/// Reads a camera sensor.yaml (EuRoC): T_BS, rate_hz, resolution, camera_model, intrinsics
/// [fx, fy, cx, cy], distortion_model, distortion_coefficients. `name` is the parent folder's.
/// Every missing or invalid field throws InputError naming the file, the field and, where known,
/// the line; values are validated (positive resolution, focal lengths and rate; coefficient count
/// matching the model; T_BS a rigid transform).
CameraCalibration readCameraCalibration(const std::filesystem::path& sensor_yaml);

/// Reads an IMU sensor.yaml (EuRoC): T_BS, rate_hz and the four positive noise parameters; the
/// optional positive `gyroscope_range` and `accelerometer_range` (the simulator writes them).
ImuCalibration readImuCalibration(const std::filesystem::path& sensor_yaml);

/// Checks a homogeneous 4x4 transform: finite, last row 0 0 0 1, rotation orthonormal within
/// kRotationOrthonormalityTolerance; returns it re-orthonormalised. Throws InputError at `where`.
SE3d checkedRigidTransform(const Eigen::Matrix4d& M, const InputLocation& where);

/// Checks the values of a calibration built in code or from another format (positive size, focal
/// lengths and rate; coefficient count matching the model). Throws InputError at `where`.
void validateCameraCalibration(const CameraCalibration& calibration, const InputLocation& where);

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
cv::Mat loadImage(const std::filesystem::path& file, const CameraCalibration& calibration);

/// Decodes a PNG file (instance masks, segmentation images) with cv::imread's `flags`. Only PNG is
/// decoded: OpenCV would try every decoder whose signature matches, and some abort the process on
/// damaged input (GDCM's DICOM reader asserts). Throws InputError naming the file when it cannot
/// be read, is not a PNG file or cannot be decoded.
cv::Mat decodePngFile(const std::filesystem::path& file, int flags);

}  // namespace superdyna::io

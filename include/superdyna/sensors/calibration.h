#pragma once
// Camera and IMU calibration as every reader produces it (EuRoC / Kalibr sensor.yaml, KITTI
// calib.txt, and later bags and live sensors) and the pipeline consumes it. The parsers live in
// io/calibration.h; nothing here depends on a file format.
//
// Frames: B is the body frame (on EuRoC the IMU frame), C a camera, I the IMU. T_b_c is the pose
// of the camera in the body frame (p_b = T_b_c * p_c), which is what EuRoC calls T_BS of a sensor.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "superdyna/core/camera_model.h"
#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"

namespace superdyna::sensors {

/// Projection model of a camera (the distortion model is superdyna::DistortionModel).
enum class ProjectionModel { kPinhole };

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

}  // namespace superdyna::sensors

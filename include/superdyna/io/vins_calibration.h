#pragma once
// Calibration in VINS-Fusion's format (VIODE ships its rig this way): an OpenCV FileStorage YAML
// with num_of_cam, body_T_cam0 / body_T_cam1 (4x4, the camera in the IMU = body frame),
// cam0_calib / cam1_calib (camera files beside it: model_type PINHOLE with k1 k2 p1 p2 and fx fy
// cx cy, or KANNALA_BRANDT with k2 k3 k4 k5 and mu mv u0 v0), image_width / image_height and the
// IMU noise acc_n, gyr_n, acc_w, gyr_w. Read with OpenCV's FileStorage, the parser VINS itself
// uses. The format has no rates: the caller gives them (a bag source measures them).
//
// VINS calls acc_n / gyr_n "measurement noise standard deviation" and feeds them to its
// continuous-time propagation; they are taken as the noise densities (and acc_w / gyr_w as the
// random walks) of sensors::ImuCalibration. VINS configs inflate them well above the sensors'
// datasheet values, which makes the IMU weigh less, not wrongly.

#include <filesystem>

#include "superdyna/io/calibration.h"

namespace superdyna::io {

/// Rates the VINS format does not carry.
struct SensorRates {
  double camera_hz = 20.0;
  double imu_hz = 200.0;
};

/// Reads the rig; InputError naming the file and key for anything missing or invalid (a second
/// camera when `stereo` and num_of_cam < 2, an unsupported model_type, a non-rigid transform).
SensorRig readVinsCalibration(const std::filesystem::path& config, bool stereo, bool inertial,
                              const SensorRates& rates);

/// A calibration given as a folder of sensor.yaml files (readSensorFolder) or as a VINS-format
/// file (readVinsCalibration).
SensorRig readRigCalibration(const std::filesystem::path& path, bool stereo, bool inertial,
                             const SensorRates& rates);

}  // namespace superdyna::io

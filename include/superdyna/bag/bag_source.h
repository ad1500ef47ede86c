#pragma once
// A ROS 1 bag as a dataset source of the SLAM pipeline (io::DatasetSource): stereo or mono images,
// IMU samples and ground truth read from the topics a preset names, the calibration from
// EuRoC-style sensor.yaml files (bags carry none: VIODE ships its calibration beside its bags).
// Frames are served as the EuRoC reader serves them, so a sequence written as a bag
// (writeViodeBag) and read back gives the same frames, IMU intervals and ground truth as its
// folder: stereo pairs are the left and right messages with the same header stamp; with IMU only
// frames inside the IMU's time range; each frame's IMU samples bracket the interval since the
// previous frame (io::bracketingImu); ground truth within 1 ms of the frame. Images are decoded
// one frame at a time (a bag may be larger than the memory).

#include <filesystem>
#include <memory>
#include <string>

#include "superdyna/io/dataset_source.h"

namespace superdyna::bag {

/// The topics a bag source reads; an empty name = not read.
struct BagTopics {
  std::string cam0 = "/cam0/image_raw";
  std::string cam1 = "/cam1/image_raw";  ///< "" = a monocular bag.
  std::string imu = "/imu0";             ///< sensor_msgs/Imu with both vectors.
  /// Accelerometer and gyroscope published apart (used when `imu` is ""): merged into one stream
  /// at the gyroscope's stamps, the acceleration interpolated (sensors::mergeImuStreams).
  std::string accel;
  std::string gyro;
  std::string ground_truth = "/odometry";  ///< nav_msgs/Odometry of the body.
};

/// "viode" (and "euroc", whose official bags use cam0/cam1/imu0 too, without odometry: the ground
/// truth topic is read only when present); "tumvi" (cam0/cam1/imu0, ground truth from
/// /vrpn_client/raw_transform: the motion-capture marker's pose, not the IMU's); "openloris" (the
/// RealSense D435i of OpenLORIS-Scene: /d400/color/image_raw, /d400/accel/sample and
/// /d400/gyro/sample; its ground truth is a separate file). OptionError naming --topics otherwise.
BagTopics bagTopicsPreset(const std::string& name);

/// A topic file: a YAML map with cam0 (required), cam1, imu or accel + gyro, ground_truth (a
/// missing key = not read). InputError naming the file and key.
BagTopics readBagTopics(const std::filesystem::path& file);

/// readBagTopics when `preset_or_file` is a file, else bagTopicsPreset.
BagTopics bagTopics(const std::string& preset_or_file);

/// The bag at `bag` with the calibration `calibration`: a folder holding cam0/sensor.yaml,
/// cam1/sensor.yaml in stereo and imu0/sensor.yaml with IMU, in EuRoC's format (an EuRoC mav0
/// folder or the sequence folder holding it), or a VINS-Fusion config file as VIODE ships
/// (io/vins_calibration.h; the rates, which it lacks, measured from the bag's stamps).
/// `ground_truth_file` (TUM, EuRoC CSV or OpenLORIS's TUM with header lines; poses of the body)
/// replaces the ground-truth topic when given. InputError naming the bag, topic or file.
std::unique_ptr<io::DatasetSource> openBagSource(
    const std::filesystem::path& bag, const std::filesystem::path& calibration,
    const BagTopics& topics, const io::DatasetSourceOptions& options,
    const std::filesystem::path& ground_truth_file = {});

}  // namespace superdyna::bag

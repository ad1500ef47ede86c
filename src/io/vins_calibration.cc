#include "superdyna/io/vins_calibration.h"

#include <fmt/format.h>

#include <opencv2/core/persistence.hpp>
#include <string>

namespace superdyna::io {

namespace fs = std::filesystem;

namespace {

/// An opened FileStorage with the file it came from, for errors naming both.
struct VinsFile {
  fs::path path;
  cv::FileStorage storage;

  explicit VinsFile(const fs::path& file) : path(file) {
    if (!fs::is_regular_file(file)) throw InputError(InputLocation{file}, "file not found");
    try {
      storage.open(file.string(), cv::FileStorage::READ);
    } catch (const cv::Exception& e) {
      throw InputError(InputLocation{file}, fmt::format("not an OpenCV YAML file: {}", e.msg));
    }
    if (!storage.isOpened()) throw InputError(InputLocation{file}, "cannot be read");
  }

  cv::FileNode node(const cv::FileNode& parent, const std::string& key) const {
    const cv::FileNode found = parent[key];
    if (found.empty()) throw InputError(InputLocation{path, 0, key}, "missing");
    return found;
  }
  cv::FileNode node(const std::string& key) const { return node(storage.root(), key); }

  double number(const cv::FileNode& parent, const std::string& key) const {
    const cv::FileNode value = node(parent, key);
    if (!value.isReal() && !value.isInt()) {
      throw InputError(InputLocation{path, 0, key}, "expected a number");
    }
    return static_cast<double>(value);
  }
  double number(const std::string& key) const { return number(storage.root(), key); }

  std::string text(const std::string& key) const {
    const cv::FileNode value = node(key);
    if (!value.isString()) throw InputError(InputLocation{path, 0, key}, "expected a string");
    return static_cast<std::string>(value);
  }

  Eigen::Matrix4d matrix4(const std::string& key) const {
    cv::Mat m;
    try {
      node(key) >> m;
    } catch (const cv::Exception& e) {
      throw InputError(InputLocation{path, 0, key}, fmt::format("not an opencv-matrix: {}", e.msg));
    }
    if (m.rows != 4 || m.cols != 4) {
      throw InputError(InputLocation{path, 0, key},
                       fmt::format("expected a 4x4 matrix, got {}x{}", m.rows, m.cols));
    }
    m.convertTo(m, CV_64F);
    Eigen::Matrix4d out;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c)
        out(r, c) = m.at<double>(r, c);
    return out;
  }
};

/// Where a VINS camera model keeps its parameters (camodocal's key names).
struct VinsModel {
  const char* name;
  DistortionModel distortion;
  const char* intrinsics[4];  ///< fx, fy, cx, cy in projection_parameters.
  const char* distortion_node;
  const char* coefficients[4];  ///< In DistortionModel's order.
};

constexpr VinsModel kVinsModels[] = {
    {"PINHOLE",
     DistortionModel::kRadialTangential,
     {"fx", "fy", "cx", "cy"},
     "distortion_parameters",
     {"k1", "k2", "p1", "p2"}},
    {"KANNALA_BRANDT",
     DistortionModel::kEquidistant,
     {"mu", "mv", "u0", "v0"},
     "projection_parameters",
     {"k2", "k3", "k4", "k5"}},
};

const VinsModel* vinsModel(const std::string& name) {
  for (const VinsModel& model : kVinsModels)
    if (name == model.name) return &model;
  return nullptr;
}

/// One camera: its model file (relative to the config) and its pose in the body frame.
sensors::CameraCalibration readVinsCamera(const VinsFile& config, int index, double rate_hz) {
  const std::string calib_key = fmt::format("cam{}_calib", index);
  const fs::path file = config.path.parent_path() / config.text(calib_key);
  const VinsFile camera(file);
  sensors::CameraCalibration calibration;
  calibration.name = fmt::format("cam{}", index);
  calibration.rate_hz = rate_hz;
  const std::string pose_key = fmt::format("body_T_cam{}", index);
  calibration.T_b_c =
      checkedRigidTransform(config.matrix4(pose_key), InputLocation{config.path, 0, pose_key});
  calibration.width = static_cast<int>(camera.number("image_width"));
  calibration.height = static_cast<int>(camera.number("image_height"));
  const std::string model = camera.text("model_type");
  const VinsModel* format = vinsModel(model);
  if (!format) {
    throw InputError(InputLocation{file, 0, "model_type"},
                     fmt::format("'{}' is not supported (PINHOLE, KANNALA_BRANDT)", model));
  }
  const cv::FileNode projection = camera.node("projection_parameters");
  const cv::FileNode coefficients = camera.node(format->distortion_node);
  double* intrinsics[4] = {&calibration.fx, &calibration.fy, &calibration.cx, &calibration.cy};
  for (int k = 0; k < 4; ++k)
    *intrinsics[k] = camera.number(projection, format->intrinsics[k]);
  calibration.distortion_model = format->distortion;
  for (const char* key : format->coefficients)
    calibration.distortion.push_back(camera.number(coefficients, key));
  validateCameraCalibration(calibration, InputLocation{file});
  return calibration;
}

sensors::ImuCalibration readVinsImu(const VinsFile& config, double rate_hz) {
  if (config.number("imu") != 1.0) {
    throw InputError(InputLocation{config.path, 0, "imu"}, "the rig has no IMU (imu: 0)");
  }
  sensors::ImuCalibration imu;  // the IMU is the body frame in VINS
  imu.rate_hz = rate_hz;
  imu.accelerometer_noise_density = config.number("acc_n");
  imu.gyroscope_noise_density = config.number("gyr_n");
  imu.accelerometer_random_walk = config.number("acc_w");
  imu.gyroscope_random_walk = config.number("gyr_w");
  for (const char* key : {"acc_n", "gyr_n", "acc_w", "gyr_w"}) {
    if (!(config.number(key) > 0.0)) {
      throw InputError(InputLocation{config.path, 0, key}, "must be positive");
    }
  }
  return imu;
}

}  // namespace

SensorRig readVinsCalibration(const fs::path& config, bool stereo, bool inertial,
                              const SensorRates& rates) {
  const VinsFile file(config);
  if (stereo && file.number("num_of_cam") < 2) {
    throw InputError(InputLocation{config, 0, "num_of_cam"},
                     "a stereo mode needs two cameras: run a mono mode");
  }
  SensorRig rig;
  rig.camera0 = readVinsCamera(file, 0, rates.camera_hz);
  if (stereo) rig.camera1 = readVinsCamera(file, 1, rates.camera_hz);
  if (inertial) rig.imu = readVinsImu(file, rates.imu_hz);
  return rig;
}

SensorRig readRigCalibration(const fs::path& path, bool stereo, bool inertial,
                             const SensorRates& rates) {
  if (fs::is_regular_file(path)) return readVinsCalibration(path, stereo, inertial, rates);
  return readSensorFolder(path, stereo, inertial);
}

}  // namespace superdyna::io

#include "superdyna/io/calibration.h"

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <string_view>
#include <vector>

#include "superdyna/io/text_table.h"
#include "superdyna/io/yaml_file.h"

namespace superdyna::io {

namespace fs = std::filesystem;

namespace {

void requirePositive(double value, const std::string& what, const InputLocation& where) {
  if (!(value > 0.0))
    throw InputError(where, fmt::format("{} must be positive, found {}", what, value));
}

void requireDistortionCount(DistortionModel model, std::size_t count, const InputLocation& where) {
  const bool ok = model == DistortionModel::kRadialTangential ? count == 4 || count == 5
                  : model == DistortionModel::kEquidistant    ? count == 4
                                                              : count == 0;
  if (ok) return;
  const char* expected = model == DistortionModel::kRadialTangential ? "4 or 5 (k1 k2 p1 p2 [k3])"
                         : model == DistortionModel::kEquidistant    ? "4 (k1 k2 k3 k4)"
                                                                     : "no";
  throw InputError(where, fmt::format("distortion model '{}' takes {} coefficients, found {}",
                                      toString(model), expected, count));
}

/// A list of exactly `count` numbers.
std::vector<double> exactNumbers(const YamlFile& yaml, const YAML::Node& node,
                                 const std::string& field, std::size_t count) {
  std::vector<double> values = yaml.numbers(node, field);
  if (values.size() != count) {
    throw InputError(yaml.at(node, field),
                     fmt::format("expected {} values, found {}", count, values.size()));
  }
  return values;
}

double positiveNumber(const YamlFile& yaml, const std::string& key) {
  const YAML::Node node = yaml.child(key);
  const double value = yaml.number(node, key);
  requirePositive(value, key, yaml.at(node, key));
  return value;
}

/// An OpenCV-style matrix {rows: 4, cols: 4, data: [16 numbers]} holding a rigid transform.
SE3d readTransform(const YamlFile& yaml, const std::string& key) {
  const YAML::Node node = yaml.child(key);
  for (const char* dimension : {"rows", "cols"}) {
    const std::string field = key + "." + dimension;
    const YAML::Node size = yaml.child(node, dimension, field);
    const double value = yaml.number(size, field);
    if (value != 4.0)
      throw InputError(yaml.at(size, field), fmt::format("expected 4, found {}", value));
  }
  const YAML::Node data = yaml.child(node, "data", key + ".data");
  const std::vector<double> values = exactNumbers(yaml, data, key + ".data", 16);
  const Eigen::Matrix4d M =
      Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(values.data());
  return checkedRigidTransform(M, yaml.at(data, key));
}

/// A pixel count: a positive whole number.
int pixelCount(double value, const std::string& what, const InputLocation& where) {
  if (!(value > 0.0) || value != std::floor(value) || value > 1e6) {
    throw InputError(
        where, fmt::format("{} must be a positive whole number of pixels, found {}", what, value));
  }
  return static_cast<int>(value);
}

void readResolution(const YamlFile& yaml, sensors::CameraCalibration& calibration) {
  const YAML::Node node = yaml.child("resolution");
  const std::vector<double> size = exactNumbers(yaml, node, "resolution", 2);
  calibration.width = pixelCount(size[0], "width", yaml.at(node, "resolution"));
  calibration.height = pixelCount(size[1], "height", yaml.at(node, "resolution"));
}

void readIntrinsics(const YamlFile& yaml, sensors::CameraCalibration& calibration) {
  const YAML::Node node = yaml.child("intrinsics");
  const std::vector<double> k = exactNumbers(yaml, node, "intrinsics", 4);
  requirePositive(k[0], "fx", yaml.at(node, "intrinsics"));
  requirePositive(k[1], "fy", yaml.at(node, "intrinsics"));
  calibration.fx = k[0];
  calibration.fy = k[1];
  calibration.cx = k[2];
  calibration.cy = k[3];
}

void readDistortion(const YamlFile& yaml, sensors::CameraCalibration& calibration) {
  const YAML::Node model = yaml.child("distortion_model");
  calibration.distortion_model = parseDistortionModel(yaml.scalar(model, "distortion_model"),
                                                      yaml.at(model, "distortion_model"));
  // Undistorted ("none") calibrations may omit the coefficients or give zeros.
  const std::string key = "distortion_coefficients";
  if (calibration.distortion_model == DistortionModel::kNone && !yaml.has(key)) return;
  const YAML::Node node = yaml.child(key);
  std::vector<double> coefficients = yaml.numbers(node, key);
  if (calibration.distortion_model == DistortionModel::kNone) {
    for (double c : coefficients) {
      if (c != 0.0) throw InputError(yaml.at(node, key), "non-zero coefficients for model 'none'");
    }
    coefficients.clear();
  }
  requireDistortionCount(calibration.distortion_model, coefficients.size(), yaml.at(node, key));
  calibration.distortion = std::move(coefficients);
}

}  // namespace

sensors::ProjectionModel parseProjectionModel(std::string_view name, const InputLocation& where) {
  if (name == "pinhole") return sensors::ProjectionModel::kPinhole;
  throw InputError(where, fmt::format("unsupported camera model '{}' (only 'pinhole')", name));
}

DistortionModel parseDistortionModel(std::string_view name, const InputLocation& where) {
  if (const auto model = superdyna::parseDistortionModel(std::string(name))) return *model;
  throw InputError(where, fmt::format("unsupported distortion model '{}' (radial-tangential, "
                                      "radtan, plumb_bob, equidistant, fisheye or none)",
                                      name));
}

sensors::CameraCalibration readCameraCalibration(const fs::path& sensor_yaml) {
  const YamlFile yaml = YamlFile::load(sensor_yaml);
  sensors::CameraCalibration calibration;
  calibration.name = sensor_yaml.parent_path().filename().string();
  calibration.T_b_c = readTransform(yaml, "T_BS");
  calibration.rate_hz = positiveNumber(yaml, "rate_hz");
  readResolution(yaml, calibration);
  const YAML::Node model = yaml.child("camera_model");
  calibration.model =
      parseProjectionModel(yaml.scalar(model, "camera_model"), yaml.at(model, "camera_model"));
  readIntrinsics(yaml, calibration);
  readDistortion(yaml, calibration);
  return calibration;
}

sensors::ImuCalibration readImuCalibration(const fs::path& sensor_yaml) {
  const YamlFile yaml = YamlFile::load(sensor_yaml);
  sensors::ImuCalibration calibration;
  calibration.T_b_i = readTransform(yaml, "T_BS");
  calibration.rate_hz = positiveNumber(yaml, "rate_hz");
  calibration.gyroscope_noise_density = positiveNumber(yaml, "gyroscope_noise_density");
  calibration.gyroscope_random_walk = positiveNumber(yaml, "gyroscope_random_walk");
  calibration.accelerometer_noise_density = positiveNumber(yaml, "accelerometer_noise_density");
  calibration.accelerometer_random_walk = positiveNumber(yaml, "accelerometer_random_walk");
  if (yaml.has("gyroscope_range"))
    calibration.gyroscope_range = positiveNumber(yaml, "gyroscope_range");
  if (yaml.has("accelerometer_range"))
    calibration.accelerometer_range = positiveNumber(yaml, "accelerometer_range");
  return calibration;
}

SE3d checkedRigidTransform(const Eigen::Matrix4d& M, const InputLocation& where) {
  if (!M.allFinite()) throw InputError(where, "transform has non-finite entries");
  if (M.row(3) != Eigen::RowVector4d(0.0, 0.0, 0.0, 1.0)) {
    throw InputError(where, fmt::format("last row of the transform is [{} {} {} {}], expected "
                                        "[0 0 0 1]",
                                        M(3, 0), M(3, 1), M(3, 2), M(3, 3)));
  }
  requireRotationMatrix(M.topLeftCorner<3, 3>(), where);
  return SE3d::fromMatrix(M);
}

void validateCameraCalibration(const sensors::CameraCalibration& calibration,
                               const InputLocation& where) {
  pixelCount(calibration.width, "width", where);
  pixelCount(calibration.height, "height", where);
  requirePositive(calibration.rate_hz, "rate_hz", where);
  requirePositive(calibration.fx, "fx", where);
  requirePositive(calibration.fy, "fy", where);
  requireDistortionCount(calibration.distortion_model, calibration.distortion.size(), where);
}

cv::Mat loadImage(const fs::path& file, const sensors::CameraCalibration& calibration) {
  if (!fs::is_regular_file(file))
    throw InputError(InputLocation{file}, "image file does not exist");
  const cv::Mat image = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
  if (image.empty()) {
    throw InputError(InputLocation{file},
                     "cannot decode the image (corrupt, truncated or not an image format)");
  }
  if (image.cols != calibration.width || image.rows != calibration.height) {
    throw InputError(InputLocation{file},
                     fmt::format("image is {}x{}, expected {}x{} (resolution of {})", image.cols,
                                 image.rows, calibration.width, calibration.height,
                                 calibration.name.empty() ? "the calibration" : calibration.name));
  }
  return image;
}

cv::Mat decodePngFile(const fs::path& file, int flags) {
  static constexpr std::string_view kPngSignature = "\x89PNG\r\n\x1a\n";
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(InputLocation{file}, "cannot open the image file");
  const std::vector<char> bytes((std::istreambuf_iterator<char>(in)),
                                std::istreambuf_iterator<char>());
  if (!std::string_view(bytes.data(), bytes.size()).starts_with(kPngSignature))
    throw InputError(InputLocation{file}, "not a PNG image (no PNG signature at its start)");
  const cv::Mat image = cv::imdecode(bytes, flags);
  if (image.empty()) throw InputError(InputLocation{file}, "cannot decode the PNG image");
  return image;
}

SensorRig readSensorFolder(const std::filesystem::path& folder, bool stereo, bool inertial) {
  namespace fs = std::filesystem;
  fs::path root = folder;
  if (!fs::exists(root / "cam0" / "sensor.yaml")) {
    root = folder / "mav0";
    if (!fs::exists(root / "cam0" / "sensor.yaml")) {
      throw InputError(InputLocation{folder},
                       "no cam0/sensor.yaml here or in mav0/ (a calibration folder holds "
                       "EuRoC-style sensor.yaml files: cam0/, cam1/ for stereo, imu0/ with IMU)");
    }
  }
  SensorRig rig;
  rig.camera0 = readCameraCalibration(root / "cam0" / "sensor.yaml");
  if (stereo) rig.camera1 = readCameraCalibration(root / "cam1" / "sensor.yaml");
  if (inertial) rig.imu = readImuCalibration(root / "imu0" / "sensor.yaml");
  return rig;
}

}  // namespace superdyna::io

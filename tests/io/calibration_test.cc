#include "superdyna/io/calibration.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "superdyna/core/error.h"
#include "superdyna/io/yaml_file.h"
#include "support/test_support.h"

namespace superdyna::io {
namespace {

using test::readFile;
using test::ScratchDir;
using test::writeFile;

constexpr const char* kCam0Yaml = "data/euroc/V1_01_easy_micro/mav0/cam0/sensor.yaml";
constexpr const char* kCam1Yaml = "data/euroc/V1_01_easy_micro/mav0/cam1/sensor.yaml";
constexpr const char* kImuYaml = "data/euroc/V1_01_easy_micro/mav0/imu0/sensor.yaml";

/// A camera sensor.yaml in the EuRoC layout (OpenCV directive first); cases edit it with
/// replaced().
std::string cameraYaml() {
  return "%YAML:1.0\n"                                                 // line 1
         "sensor_type: camera\n"                                       // line 2
         "T_BS:\n"                                                     // line 3
         "  cols: 4\n"                                                 // line 4
         "  rows: 4\n"                                                 // line 5
         "  data: [0.0, -1.0, 0.0, 0.1,\n"                             // line 6
         "         1.0, 0.0, 0.0, 0.2,\n"                              // line 7
         "         0.0, 0.0, 1.0, 0.3,\n"                              // line 8
         "         0.0, 0.0, 0.0, 1.0]\n"                              // line 9
         "rate_hz: 20\n"                                               // line 10
         "resolution: [752, 480]\n"                                    // line 11
         "camera_model: pinhole\n"                                     // line 12
         "intrinsics: [458.654, 457.296, 367.215, 248.375]\n"          // line 13
         "distortion_model: radial-tangential\n"                       // line 14
         "distortion_coefficients: [-0.28, 0.07, 0.0002, 1.7e-05]\n";  // line 15
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto pos = text.find(from);
  EXPECT_NE(pos, std::string::npos) << "'" << from << "' not in the template";
  if (pos != std::string::npos) text.replace(pos, from.size(), to);
  return text;
}

TEST(CalibrationTest, ReadsEurocCam0AsInTheYaml) {
  SUPERDYNA_REQUIRE_SHARED(file, kCam0Yaml);
  const sensors::CameraCalibration c = readCameraCalibration(file);
  EXPECT_EQ(c.name, "cam0");
  EXPECT_EQ(c.width, 752);
  EXPECT_EQ(c.height, 480);
  EXPECT_DOUBLE_EQ(c.rate_hz, 20.0);
  EXPECT_EQ(c.model, sensors::ProjectionModel::kPinhole);
  EXPECT_DOUBLE_EQ(c.fx, 458.654);
  EXPECT_DOUBLE_EQ(c.fy, 457.296);
  EXPECT_DOUBLE_EQ(c.cx, 367.215);
  EXPECT_DOUBLE_EQ(c.cy, 248.375);
  EXPECT_EQ(c.distortion_model, DistortionModel::kRadialTangential);
  ASSERT_EQ(c.distortion.size(), 4u);
  EXPECT_DOUBLE_EQ(c.distortion[0], -0.28340811);
  EXPECT_DOUBLE_EQ(c.distortion[1], 0.07395907);
  EXPECT_DOUBLE_EQ(c.distortion[2], 0.00019359);
  EXPECT_DOUBLE_EQ(c.distortion[3], 1.76187114e-05);

  // T_BS row-major; re-orthonormalisation moves the rotation by less than its rounding.
  const Eigen::Matrix4d T = c.T_b_c.matrix();
  EXPECT_NEAR(T(0, 0), 0.0148655429818, 1e-9);
  EXPECT_NEAR(T(0, 1), -0.999880929698, 1e-9);
  EXPECT_NEAR(T(1, 0), 0.999557249008, 1e-9);
  EXPECT_NEAR(T(2, 2), 0.999660727178, 1e-9);
  EXPECT_DOUBLE_EQ(T(0, 3), -0.0216401454975);
  EXPECT_DOUBLE_EQ(T(1, 3), -0.064676986768);
  EXPECT_DOUBLE_EQ(T(2, 3), 0.00981073058949);

  const cv::Mat K = c.cameraMatrix();
  EXPECT_EQ(K.type(), CV_64F);
  EXPECT_DOUBLE_EQ(K.at<double>(0, 0), 458.654);
  EXPECT_DOUBLE_EQ(K.at<double>(1, 2), 248.375);
  EXPECT_DOUBLE_EQ(K.at<double>(2, 2), 1.0);
  EXPECT_DOUBLE_EQ(K.at<double>(0, 1), 0.0);
  const cv::Mat d = c.distortionCoefficients();
  EXPECT_EQ(d.cols, 4);
  EXPECT_DOUBLE_EQ(d.at<double>(0, 1), 0.07395907);
}

TEST(CalibrationTest, ReadsEurocCam1AndImu) {
  SUPERDYNA_REQUIRE_SHARED(cam1_file, kCam1Yaml);
  const sensors::CameraCalibration cam1 = readCameraCalibration(cam1_file);
  EXPECT_EQ(cam1.name, "cam1");
  EXPECT_DOUBLE_EQ(cam1.fx, 457.587);
  EXPECT_DOUBLE_EQ(cam1.fy, 456.134);
  EXPECT_DOUBLE_EQ(cam1.cx, 379.999);
  EXPECT_DOUBLE_EQ(cam1.cy, 255.238);
  EXPECT_DOUBLE_EQ(cam1.distortion[0], -0.28368365);
  EXPECT_DOUBLE_EQ(cam1.distortion[3], -3.55590700e-05);
  EXPECT_DOUBLE_EQ(cam1.T_b_c.t.y(), 0.0453689425024);

  SUPERDYNA_REQUIRE_SHARED(cam0_file, kCam0Yaml);
  const sensors::CameraCalibration cam0 = readCameraCalibration(cam0_file);
  // The EuRoC stereo baseline is about 11 cm.
  EXPECT_NEAR((cam0.T_b_c.inverse() * cam1.T_b_c).t.norm(), 0.110, 0.001);

  SUPERDYNA_REQUIRE_SHARED(imu_file, kImuYaml);
  const sensors::ImuCalibration imu = readImuCalibration(imu_file);
  EXPECT_DOUBLE_EQ(imu.rate_hz, 200.0);
  EXPECT_EQ(imu.periodNs(), 5'000'000);
  EXPECT_DOUBLE_EQ(imu.gyroscope_noise_density, 1.6968e-04);
  EXPECT_DOUBLE_EQ(imu.gyroscope_random_walk, 1.9393e-05);
  EXPECT_DOUBLE_EQ(imu.accelerometer_noise_density, 2.0e-3);
  EXPECT_DOUBLE_EQ(imu.accelerometer_random_walk, 3.0e-3);
  EXPECT_TRUE(imu.T_b_i.matrix().isIdentity(0.0));
}

TEST(CalibrationTest, AcceptsDistortionModelAliases) {
  ScratchDir dir("calib_alias");
  const auto file = dir / "sensor.yaml";
  for (const char* name : {"radtan", "plumb_bob"}) {
    writeFile(file, replaced(cameraYaml(), "radial-tangential", name));
    EXPECT_EQ(readCameraCalibration(file).distortion_model, DistortionModel::kRadialTangential);
  }
  writeFile(file, replaced(replaced(cameraYaml(), "radial-tangential", "fisheye"),
                           "[-0.28, 0.07, 0.0002, 1.7e-05]", "[0.1, 0.2, 0.3, 0.4]"));
  const sensors::CameraCalibration fisheye = readCameraCalibration(file);
  EXPECT_EQ(fisheye.distortion_model, DistortionModel::kEquidistant);
  EXPECT_DOUBLE_EQ(fisheye.distortionCoefficients().at<double>(0, 3), 0.4);
  writeFile(file, replaced(cameraYaml(), "1.7e-05]", "1.7e-05, 0.001]"));
  EXPECT_EQ(readCameraCalibration(file).distortion.size(), 5u);  // radtan with k3
  writeFile(file, replaced(replaced(cameraYaml(), "radial-tangential", "none"),
                           "[-0.28, 0.07, 0.0002, 1.7e-05]", "[0, 0, 0, 0]"));
  EXPECT_TRUE(readCameraCalibration(file).distortion.empty());
  // A file without the OpenCV directive parses too.
  writeFile(file, replaced(cameraYaml(), "%YAML:1.0\n", ""));
  EXPECT_DOUBLE_EQ(readCameraCalibration(file).fx, 458.654);
  // T_BS is a rotation of +90 degrees about z with translation (0.1, 0.2, 0.3).
  const SE3d T = readCameraCalibration(file).T_b_c;
  EXPECT_NEAR((T * Eigen::Vector3d(1, 0, 0) - Eigen::Vector3d(0.1, 1.2, 0.3)).norm(), 0.0, 1e-12);
}

TEST(CalibrationTest, RejectsBadCameraFilesNamingFileLineAndField) {
  ScratchDir dir("calib_bad");
  const auto file = dir / "sensor.yaml";
  struct Case {
    std::string content;
    std::vector<std::string> fragments;
  };
  const std::string yaml = cameraYaml();
  const std::vector<Case> cases = {
      {replaced(yaml, "intrinsics: [458.654, 457.296, 367.215, 248.375]\n", ""),
       {"sensor.yaml [intrinsics]: missing field"}},
      {replaced(yaml, "[458.654, 457.296, 367.215, 248.375]", "[458.654, 457.296, 367.215]"),
       {"sensor.yaml:13 [intrinsics]", "expected 4 values, found 3"}},
      {replaced(yaml, "[458.654, 457.296", "[-458.654, 457.296"),
       {"sensor.yaml:13 [intrinsics]", "fx must be positive"}},
      {replaced(yaml, "457.296", "abc"),
       {"sensor.yaml:13 [intrinsics[1]]", "'abc' is not a number"}},
      {replaced(yaml, "[752, 480]", "[752, 0]"), {"sensor.yaml:11 [resolution]", "height"}},
      {replaced(yaml, "[752, 480]", "[752.5, 480]"), {"sensor.yaml:11", "whole number"}},
      {replaced(yaml, "rate_hz: 20", "rate_hz: 0"), {"sensor.yaml:10 [rate_hz]", "positive"}},
      {replaced(yaml, "rate_hz: 20\n", ""), {"[rate_hz]: missing field"}},
      {replaced(yaml, "pinhole", "omni"),
       {"sensor.yaml:12 [camera_model]", "unsupported camera model 'omni'"}},
      {replaced(yaml, "radial-tangential", "atan"),
       {"sensor.yaml:14 [distortion_model]", "unsupported distortion model 'atan'"}},
      {replaced(yaml, "radial-tangential", "equidistant"), {}},  // 4 coefficients: fine
      {replaced(yaml, "1.7e-05]", "1.7e-05, 1, 2]"),
       {"sensor.yaml:15 [distortion_coefficients]", "4 or 5", "found 6"}},
      {replaced(yaml, "  rows: 4\n", "  rows: 3\n"), {"sensor.yaml:5 [T_BS.rows]", "expected 4"}},
      {replaced(yaml, "  data: [0.0, -1.0, 0.0, 0.1,\n", "  data: [0.0, -1.0, 0.1,\n"),
       {"sensor.yaml:6 [T_BS.data]", "expected 16 values, found 15"}},
      {replaced(yaml, "0.0, 0.0, 0.0, 1.0]", "0.0, 0.0, 1.0, 1.0]"),
       {"sensor.yaml:6 [T_BS]", "last row"}},
      {replaced(yaml, "1.0, 0.0, 0.0, 0.2", "1.0, 0.1, 0.0, 0.2"),
       {"sensor.yaml:6 [T_BS]", "not orthonormal"}},
      {replaced(yaml, "0.0, 0.0, 1.0, 0.3", "0.0, 0.0, nan, 0.3"),
       {"[T_BS.data[10]]", "not finite"}},
      {replaced(yaml, "  data:", "  dat:"), {"sensor.yaml:4 [T_BS.data]: missing field"}},
      {replaced(yaml, "camera_model: pinhole\n", "camera_model: [pinhole\n"),
       {"sensor.yaml:", "YAML syntax error"}},
  };
  for (const Case& c : cases) {
    writeFile(file, c.content);
    if (c.fragments.empty()) {
      EXPECT_NO_THROW(readCameraCalibration(file));
      continue;
    }
    std::vector<std::string> fragments = c.fragments;
    fragments.resize(3);
    test::expectError([&] { readCameraCalibration(file); },
                      {fragments[0], fragments[1], fragments[2]});
  }
  test::expectError([&] { readCameraCalibration(dir / "absent.yaml"); },
                    {"absent.yaml", "does not exist"});
}

TEST(CalibrationTest, YamlSyntaxErrorNamesTheFileLine) {
  ScratchDir dir("calib_syntax");
  const auto file = dir / "sensor.yaml";
  // Line 3 opens a flow sequence that line 4 breaks; lines count from the OpenCV directive.
  writeFile(file, "%YAML:1.0\nrate_hz: 20\nresolution: [752, 480\ncamera_model: {a: b]\n");
  try {
    YamlFile::load(file);
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.location().file, file);
    EXPECT_GE(e.location().line, 3);
    EXPECT_LE(e.location().line, 4);
    EXPECT_NE(std::string(e.what()).find("YAML syntax error"), std::string::npos) << e.what();
  }
}

TEST(CalibrationTest, RejectsBadImuFiles) {
  SUPERDYNA_REQUIRE_SHARED(imu_file, kImuYaml);
  ScratchDir dir("calib_imu");
  const auto file = dir / "sensor.yaml";
  const std::string yaml = readFile(imu_file);
  writeFile(file, replaced(yaml, "gyroscope_random_walk: 1.9393e-05", "gyroscope_random_walk: -1"));
  test::expectError([&] { readImuCalibration(file); },
                    {"sensor.yaml:18 [gyroscope_random_walk]", "must be positive"});
  writeFile(file, replaced(yaml, "accelerometer_noise_density: 2.0000e-3", ""));
  test::expectError([&] { readImuCalibration(file); },
                    {"sensor.yaml [accelerometer_noise_density]: missing field"});
  writeFile(file, replaced(yaml, "rate_hz: 200", "rate_hz: fast"));
  test::expectError([&] { readImuCalibration(file); }, {"[rate_hz]", "'fast' is not a number"});
}

TEST(CalibrationTest, ValidatesTransformsAndCalibrationsBuiltInCode) {
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  M(0, 3) = 1.0;
  M.topLeftCorner<3, 3>() +=
      1e-4 * Eigen::Matrix3d::Ones();  // within tolerance: re-orthonormalised
  const SE3d T = checkedRigidTransform(M, InputLocation{"x.yaml"});
  EXPECT_NEAR((T.rotation().transpose() * T.rotation() - Eigen::Matrix3d::Identity()).norm(), 0.0,
              1e-12);
  M(1, 1) = -1.0;  // a reflection
  test::expectError([&] { checkedRigidTransform(M, InputLocation{"x.yaml"}); },
                    {"x.yaml", "not orthonormal"});

  sensors::CameraCalibration c;
  c.width = 640;
  c.height = 480;
  c.rate_hz = 30.0;
  c.fx = c.fy = 500.0;
  EXPECT_NO_THROW(validateCameraCalibration(c, InputLocation{"c"}));
  c.distortion = {0.1};
  test::expectError([&] { validateCameraCalibration(c, InputLocation{"c"}); },
                    {"distortion model 'none' takes no coefficients, found 1"});
  c.distortion_model = DistortionModel::kEquidistant;
  test::expectError([&] { validateCameraCalibration(c, InputLocation{"c"}); }, {"4 (k1 k2 k3 k4)"});
}

TEST(CalibrationTest, LoadsImagesCheckedAgainstTheCalibration) {
  SUPERDYNA_REQUIRE_SHARED(cam0_file, kCam0Yaml);
  SUPERDYNA_REQUIRE_SHARED(png,
                           "data/euroc/V1_01_easy_micro/mav0/cam0/data/1403715273262142976.png");
  const sensors::CameraCalibration cam0 = readCameraCalibration(cam0_file);
  const cv::Mat image = loadImage(png, cam0);
  EXPECT_EQ(image.type(), CV_8UC1);
  EXPECT_EQ(image.cols, 752);
  EXPECT_EQ(image.rows, 480);
  EXPECT_GT(cv::mean(image)[0], 10.0);  // a real picture, not a blank

  ScratchDir dir("calib_image");
  const auto small = dir / "small.png";
  cv::Mat colour(480, 640, CV_8UC3, cv::Scalar(10, 20, 30));
  ASSERT_TRUE(cv::imwrite(small.string(), colour));
  test::expectError([&] { loadImage(small, cam0); },
                    {"small.png", "is 640x480, expected 752x480", "cam0"});
  sensors::CameraCalibration vga = cam0;
  vga.width = 640;
  EXPECT_EQ(loadImage(small, vga).type(), CV_8UC1);  // colour converted to grayscale

  const auto garbage = dir / "garbage.png";
  writeFile(garbage, "\x89PNG this is not really an image");
  test::expectError([&] { loadImage(garbage, cam0); }, {"garbage.png", "cannot decode"});
  test::expectError([&] { loadImage(dir / "absent.png", cam0); }, {"absent.png", "does not exist"});
}

}  // namespace
}  // namespace superdyna::io

#include "superdyna/io/vins_calibration.h"

#include <gtest/gtest.h>

#include "support/test_support.h"

namespace superdyna::io {
namespace {

namespace fs = std::filesystem;

TEST(VinsCalibration, ReadsViodesRig) {
  SUPERDYNA_REQUIRE_SHARED(config, "data/viode_meta/calibration.yaml");
  const SensorRig rig = readVinsCalibration(config, true, true, {.camera_hz = 20, .imu_hz = 200});
  EXPECT_EQ(rig.camera0.width, 752);
  EXPECT_EQ(rig.camera0.height, 480);
  EXPECT_EQ(rig.camera0.fx, 376.0);
  EXPECT_EQ(rig.camera0.cy, 240.0);
  EXPECT_EQ(rig.camera0.rate_hz, 20.0);
  EXPECT_EQ(rig.camera0.distortion_model, DistortionModel::kRadialTangential);
  // body_T_cam0: camera z along body x, camera x along body y.
  const Eigen::Matrix3d R = rig.camera0.T_b_c.rotation();
  EXPECT_TRUE(R.col(2).isApprox(Eigen::Vector3d::UnitX()));
  EXPECT_TRUE(R.col(0).isApprox(Eigen::Vector3d::UnitY()));
  ASSERT_TRUE(rig.camera1.has_value());
  EXPECT_NEAR((rig.camera1->T_b_c.t - rig.camera0.T_b_c.t).norm(), 0.05, 1e-12);  // baseline
  ASSERT_TRUE(rig.imu.has_value());
  EXPECT_EQ(rig.imu->accelerometer_noise_density, 0.2);
  EXPECT_EQ(rig.imu->gyroscope_noise_density, 0.05);
  EXPECT_EQ(rig.imu->accelerometer_random_walk, 0.02);
  EXPECT_EQ(rig.imu->gyroscope_random_walk, 4.0e-5);
  EXPECT_EQ(rig.imu->rate_hz, 200.0);
  EXPECT_TRUE(rig.imu->T_b_i.t.isZero());
  // The same through readRigCalibration, which tells a file from a sensor.yaml folder.
  EXPECT_EQ(readRigCalibration(config, false, false, {}).camera0.fx, 376.0);
}

TEST(VinsCalibration, ErrorsNameTheFileAndKey) {
  const test::ScratchDir dir("vins_calibration");
  const std::string pose =
      "body_T_cam0: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n"
      "   data: [0, 0, 1, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1]\n";
  test::writeFile(dir / "config.yaml",
                  "%YAML:1.0\nimu: 1\nnum_of_cam: 1\ncam0_calib: \"cam.yaml\"\n" + pose +
                      "acc_n: 0.1\ngyr_n: 0.01\nacc_w: 0.001\n");
  test::writeFile(dir / "cam.yaml",
                  "%YAML:1.0\n---\nmodel_type: MEI\nimage_width: 640\nimage_height: 480\n");
  test::expectError([&] { readVinsCalibration(dir / "config.yaml", true, false, {}); },
                    {"config.yaml", "num_of_cam", "two cameras"});
  test::expectError([&] { readVinsCalibration(dir / "config.yaml", false, false, {}); },
                    {"cam.yaml", "model_type", "MEI", "not supported"});
  test::writeFile(dir / "cam.yaml",
                  "%YAML:1.0\n---\nmodel_type: KANNALA_BRANDT\nimage_width: 640\n"
                  "image_height: 480\nprojection_parameters:\n   k2: 0.1\n   k3: 0.01\n"
                  "   k4: 0.0\n   k5: 0.0\n   mu: 300.0\n   mv: 301.0\n   u0: 320.0\n"
                  "   v0: 240.0\n");
  const SensorRig rig = readVinsCalibration(dir / "config.yaml", false, false, {});
  EXPECT_EQ(rig.camera0.distortion_model, DistortionModel::kEquidistant);
  EXPECT_EQ(rig.camera0.distortion, (std::vector<double>{0.1, 0.01, 0.0, 0.0}));
  EXPECT_EQ(rig.camera0.fy, 301.0);
  test::expectError([&] { readVinsCalibration(dir / "config.yaml", false, true, {}); },
                    {"config.yaml", "gyr_w", "missing"});
  test::expectError([&] { readVinsCalibration(dir / "none.yaml", false, false, {}); },
                    {"none.yaml", "not found"});
  test::writeFile(dir / "broken.yaml", "%YAML:1.0\nimu: [1, \n");
  test::expectError([&] { readVinsCalibration(dir / "broken.yaml", false, false, {}); },
                    {"broken.yaml"});
}

}  // namespace
}  // namespace superdyna::io

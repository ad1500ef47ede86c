#include "superdyna/core/camera_model.h"

#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <random>

#include "superdyna/core/error.h"

namespace superdyna {
namespace {

// EuRoC V1_01 cam0 calibration (radial-tangential).
CameraModel eurocCam0() {
  return CameraModel(752, 480, 458.654, 457.296, 367.215, 248.375,
                     DistortionModel::kRadialTangential,
                     {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05});
}

std::vector<cv::Point3d> randomPointsInView(std::mt19937& rng, int count) {
  std::uniform_real_distribution<double> xy(-0.7, 0.7), depth(0.5, 20.0);
  std::vector<cv::Point3d> points;
  for (int i = 0; i < count; ++i) {
    const double z = depth(rng);
    points.emplace_back(xy(rng) * z, xy(rng) * z * 0.6, z);
  }
  return points;
}

TEST(CameraModelTest, RadTanProjectionMatchesOpenCV) {
  const CameraModel camera = eurocCam0();
  std::mt19937 rng(3);
  const auto points = randomPointsInView(rng, 200);
  const cv::Matx33d K(camera.fx(), 0, camera.cx(), 0, camera.fy(), camera.cy(), 0, 0, 1);
  std::vector<cv::Point2d> expected;
  cv::projectPoints(points, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K,
                    std::vector<double>(camera.coefficients()), expected);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto pixel = camera.project({points[i].x, points[i].y, points[i].z});
    ASSERT_TRUE(pixel);
    EXPECT_NEAR(pixel->x(), expected[i].x, 1e-9);
    EXPECT_NEAR(pixel->y(), expected[i].y, 1e-9);
  }
}

TEST(CameraModelTest, EquidistantProjectionMatchesOpenCVFisheye) {
  const CameraModel camera(512, 512, 190.97, 190.98, 254.93, 256.90, DistortionModel::kEquidistant,
                           {0.0034823, 0.00071504, -0.0020532, 0.00020293});  // TUM-VI cam0
  std::mt19937 rng(4);
  const auto points = randomPointsInView(rng, 200);
  const cv::Matx33d K(camera.fx(), 0, camera.cx(), 0, camera.fy(), camera.cy(), 0, 0, 1);
  std::vector<cv::Point2d> expected;
  cv::fisheye::projectPoints(points, expected, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K,
                             cv::Vec4d(0.0034823, 0.00071504, -0.0020532, 0.00020293));
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto pixel = camera.project({points[i].x, points[i].y, points[i].z});
    ASSERT_TRUE(pixel);
    EXPECT_NEAR(pixel->x(), expected[i].x, 1e-8);
    EXPECT_NEAR(pixel->y(), expected[i].y, 1e-8);
  }
}

TEST(CameraModelTest, UnprojectInvertsProjectOverTheWholeImage) {
  for (const CameraModel& camera :
       {eurocCam0(), CameraModel(640, 480, 400, 400, 320, 240),
        CameraModel(512, 512, 190.97, 190.98, 254.93, 256.90, DistortionModel::kEquidistant,
                    {0.0034823, 0.00071504, -0.0020532, 0.00020293})}) {
    for (int v = 0; v < camera.height(); v += 37) {
      for (int u = 0; u < camera.width(); u += 41) {
        const Eigen::Vector2d pixel(u, v);
        const auto bearing = camera.unproject(pixel);
        ASSERT_TRUE(bearing) << u << "," << v;
        EXPECT_NEAR(bearing->norm(), 1.0, 1e-12);
        if (bearing->z() < 0.05) continue;  // fisheye corners look sideways or backwards
        const auto back = camera.project(*bearing * 3.0);
        ASSERT_TRUE(back);
        EXPECT_LT((*back - pixel).norm(), 1e-6) << u << "," << v;
      }
    }
  }
}

TEST(CameraModelTest, RejectsPointsBehindAndBadParameters) {
  const CameraModel camera = eurocCam0();
  EXPECT_FALSE(camera.project({0.0, 0.0, -1.0}));
  EXPECT_TRUE(camera.isInImage({0.0, 0.0}));
  EXPECT_FALSE(camera.isInImage({752.0, 10.0}));
  EXPECT_THROW(CameraModel(0, 480, 1, 1, 0, 0), OptionError);
  EXPECT_THROW(CameraModel(752, 480, -1, 1, 0, 0), OptionError);
  EXPECT_THROW(CameraModel(752, 480, 1, 1, 0, 0, DistortionModel::kEquidistant, {0.1}),
               OptionError);
  EXPECT_EQ(parseDistortionModel("radtan"), DistortionModel::kRadialTangential);
  EXPECT_EQ(parseDistortionModel("fisheye"), DistortionModel::kEquidistant);
  EXPECT_FALSE(parseDistortionModel("division"));
}

}  // namespace
}  // namespace superdyna

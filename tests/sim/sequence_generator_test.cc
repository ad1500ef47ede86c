#include "superdyna/sim/sequence_generator.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "superdyna/core/error.h"
#include "superdyna/io/euroc_dataset.h"
#include "superdyna/io/text_table.h"
#include "support/test_support.h"

namespace superdyna::sim {
namespace {

namespace fs = std::filesystem;
using test::ScratchDir;

SimulationOptions shortSequence(const fs::path& out) {
  SimulationOptions options;
  options.output_dir = out;
  options.motion.duration_s = 1.5;
  options.world.scene = SceneType::kIndoor;
  options.world.dynamic = DynamicLevel::kHigh;
  options.noise = false;
  options.landmark_count = 300;
  options.seed = 5;
  return options;
}

/// One generated sequence shared by the tests of this file (rendering takes seconds).
class SequenceGeneratorTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new ScratchDir("sequence");
    SimulationOptions options = shortSequence(dir_->path() / "a");
    options.preview_path = dir_->path() / "preview.png";
    options.preview_frame = 1000;  // past the end: the last frame
    summary_ = generateSequence(options);
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static fs::path root() { return dir_->path() / "a"; }
  static fs::path mav0() { return root() / "mav0"; }

  static ScratchDir* dir_;
  static SimulationSummary summary_;
};

ScratchDir* SequenceGeneratorTest::dir_ = nullptr;
SimulationSummary SequenceGeneratorTest::summary_;

/// Rotation and position of the body after integrating the IMU from `start` (RK4 over the 200 Hz
/// samples, linearly interpolated, true biases removed, gravity -9.81 z).
struct BodyState {
  Eigen::Matrix3d R;
  Eigen::Vector3d p, v;
};

BodyState integrateImu(const sensors::GroundTruthState& start,
                       std::span<const sensors::ImuSample> imu) {
  const Eigen::Vector3d g(0, 0, -9.81);
  BodyState s{start.T_w_b.rotation(), start.T_w_b.t, start.v_w};
  for (std::size_t k = 0; k + 1 < imu.size(); ++k) {
    const double dt = nsToSeconds(imu[k + 1].t_ns - imu[k].t_ns);
    const auto omega = [&](double a) {
      return Eigen::Vector3d((1 - a) * imu[k].gyro + a * imu[k + 1].gyro - start.bg);
    };
    const auto accel = [&](double a) {
      return Eigen::Vector3d((1 - a) * imu[k].accel + a * imu[k + 1].accel - start.ba);
    };
    // RK4 on (R, p, v) with R updated through the exponential map at the stage points.
    const Eigen::Matrix3d R_half = s.R * expSO3(0.5 * dt * omega(0.25));
    const Eigen::Matrix3d R_end = s.R * expSO3(dt * omega(0.5));
    const Eigen::Vector3d a0 = s.R * accel(0.0) + g;
    const Eigen::Vector3d a1 = R_half * accel(0.5) + g;
    const Eigen::Vector3d a2 = R_end * accel(1.0) + g;
    s.p += dt * s.v + dt * dt / 6.0 * (a0 + 2.0 * a1);
    s.v += dt / 6.0 * (a0 + 4.0 * a1 + a2);
    s.R = R_end;
  }
  return s;
}

TEST_F(SequenceGeneratorTest, WritesAnEurocSequenceTheReaderAccepts) {
  const io::EurocDataset dataset = io::EurocDataset::open(root());
  EXPECT_EQ(dataset.stereoFrames().size(), 31u);  // 1.5 s at 20 Hz, both ends included
  EXPECT_EQ(summary_.frames, 31);
  EXPECT_EQ(dataset.imu().size(), 301u);  // 200 Hz
  EXPECT_EQ(dataset.imu()[1].t_ns - dataset.imu()[0].t_ns, 5'000'000);
  EXPECT_EQ(dataset.groundTruth().size(), 301u);
  EXPECT_TRUE(dataset.groundTruthHasVelocityAndBiases());
  EXPECT_TRUE(dataset.warnings().empty());
  const RigOptions rig;
  const auto& cam0 = dataset.cam0Calibration();
  EXPECT_EQ(cam0.width, 752);
  EXPECT_EQ(cam0.height, 480);
  EXPECT_DOUBLE_EQ(cam0.fx, rig.fx);
  EXPECT_LT((cam0.T_b_c.matrix() - rig.T_b_c0().matrix()).norm(), 1e-9);
  const Eigen::Vector3d baseline = (cam0.T_b_c.inverse() * dataset.cam1Calibration()->T_b_c).t;
  EXPECT_LT((baseline - Eigen::Vector3d(0.11, 0, 0)).norm(), 1e-9);
  EXPECT_DOUBLE_EQ(dataset.imuCalibration()->gyroscope_noise_density, 1.6968e-4);
  const cv::Mat preview = cv::imread((dir_->path() / "preview.png").string());
  EXPECT_EQ(preview.cols, 2 * 752);
  EXPECT_EQ(preview.rows, 480);
  const cv::Mat image = io::loadImage(dataset.stereoFrames()[10].cam0, cam0);
  cv::Scalar mean, stddev;
  cv::meanStdDev(image, mean, stddev);
  EXPECT_GT(stddev[0], 20.0) << "the image should be textured";
}

TEST_F(SequenceGeneratorTest, NoiseFreeImuIntegratesToTheGroundTruth) {
  const io::EurocDataset dataset = io::EurocDataset::open(root());
  const auto& gt = dataset.groundTruth();
  const sensors::GroundTruthState& start = gt[40];
  const sensors::GroundTruthState& end = gt[240];  // 1 s later
  const BodyState s = integrateImu(start, dataset.imuBetween(start.t_ns, end.t_ns));
  EXPECT_LT((s.p - end.T_w_b.t).norm(), 1e-3);
  EXPECT_LT(rotationAngle(s.R.transpose() * end.T_w_b.rotation()) * 180.0 / M_PI, 0.01);
}

TEST_F(SequenceGeneratorTest, MasksAgreeWithTheInstanceTables) {
  std::map<int, std::string> classes;
  std::map<int, bool> ever_moving;
  for (const auto& row : io::readTextRows(mav0() / "instances.csv", io::Delimiter::kComma)) {
    classes[std::stoi(row.fields[0])] = row.fields[1];
    ever_moving[std::stoi(row.fields[0])] = row.fields[2] == "1";
  }
  ASSERT_FALSE(classes.empty());
  int moving_rows = 0;
  for (const auto& row : io::readTextRows(mav0() / "instance_states.csv", io::Delimiter::kComma)) {
    const int id = std::stoi(row.fields[1]);
    ASSERT_TRUE(classes.count(id)) << "unknown instance " << id;
    EXPECT_EQ(classes[id], "pedestrian");  // indoor scenes have people only
    if (row.fields[2] == "1") {
      EXPECT_TRUE(ever_moving[id]);
      ++moving_rows;
    }
    const cv::Mat mask = cv::imread((mav0() / "cam0/mask" / (row.fields[0] + ".png")).string(),
                                    cv::IMREAD_UNCHANGED);
    ASSERT_EQ(mask.type(), CV_16UC1);
    EXPECT_EQ(cv::countNonZero(mask == id), std::stoi(row.fields[3])) << "instance " << id;
  }
  EXPECT_GT(moving_rows, 0);
}

TEST_F(SequenceGeneratorTest, LandmarksLookTheSameInBothCameras) {
  const io::EurocDataset dataset = io::EurocDataset::open(root());
  std::map<TimeNs, std::pair<cv::Mat, cv::Mat>> images;
  for (const auto& frame : dataset.stereoFrames()) {
    images[frame.t_ns] = {cv::imread(frame.cam0.string(), cv::IMREAD_GRAYSCALE),
                          cv::imread(frame.cam1.string(), cv::IMREAD_GRAYSCALE)};
  }
  const CameraModel camera = dataset.cam0Calibration().cameraModel();
  // 9x9 patches sampled at sub-pixel positions.
  const auto patch = [](const cv::Mat& im, const Eigen::Vector2d& p) {
    cv::Mat out;
    cv::getRectSubPix(im, cv::Size(9, 9), cv::Point2f(p.x(), p.y()), out, CV_32F);
    return out;
  };
  double same_sum = 0.0, shifted_sum = 0.0;
  int textured = 0;
  for (const auto& row : io::readTextRows(mav0() / "landmarks.csv", io::Delimiter::kComma)) {
    const Eigen::Vector3d p_w(std::stod(row.fields[1]), std::stod(row.fields[2]),
                              std::stod(row.fields[3]));
    const TimeNs t = std::stoll(row.fields[4]);
    const auto gt = dataset.groundTruthNearest(t, 0);
    ASSERT_TRUE(gt);
    const SE3d T_w_c0 = gt->T_w_b * dataset.cam0Calibration().T_b_c;
    const SE3d T_w_c1 = gt->T_w_b * dataset.cam1Calibration()->T_b_c;
    const auto u0 = camera.project(T_w_c0.inverse() * p_w);
    const auto u1 = camera.project(T_w_c1.inverse() * p_w);
    if (!u0 || !u1 || !camera.isInImage(*u0, 12) || !camera.isInImage(*u1, 12)) continue;
    const auto& [left, right] = images.at(t);
    const cv::Mat p0 = patch(left, *u0);
    cv::Scalar mean, stddev;
    cv::meanStdDev(p0, mean, stddev);
    if (stddev[0] < 8.0) continue;  // flat paint: any position looks alike
    ++textured;
    same_sum += cv::mean(cv::abs(p0 - patch(right, *u1)))[0];
    shifted_sum += cv::mean(cv::abs(p0 - patch(right, *u1 + Eigen::Vector2d(4, 2))))[0];
  }
  ASSERT_GT(textured, 50);
  std::printf(
      "photometric consistency over %d textured landmarks: mean |cam0 - cam1| %.2f gray "
      "levels at the projections, %.2f a few pixels off\n",
      textured, same_sum / textured, shifted_sum / textured);
  // At the landmark's projections the two views show the same texture (sub-pixel resampling
  // differences only); a few pixels off they do not.
  EXPECT_LT(same_sum / textured, 4.0);
  EXPECT_LT(same_sum, 0.3 * shifted_sum);
}

TEST_F(SequenceGeneratorTest, SameSeedGivesIdenticalFilesAndAnotherSeedDoesNot) {
  generateSequence(shortSequence(dir_->path() / "b"));
  std::size_t compared = 0;
  for (const auto& entry : fs::recursive_directory_iterator(root())) {
    if (!entry.is_regular_file()) continue;
    const fs::path other = dir_->path() / "b" / fs::relative(entry.path(), root());
    ASSERT_TRUE(fs::exists(other)) << other;
    ASSERT_EQ(test::readFile(entry.path()), test::readFile(other)) << other;
    ++compared;
  }
  EXPECT_GT(compared, 120u);  // 31 frames x (2 images + 2 masks) + tables
  SimulationOptions options = shortSequence(dir_->path() / "c");
  options.seed = 6;
  generateSequence(options);
  const std::string name = "cam0/data.csv";
  const auto first_image = io::readTextRows(mav0() / name, io::Delimiter::kComma)[5].fields[1];
  EXPECT_NE(test::readFile(mav0() / "cam0/data" / first_image),
            test::readFile(dir_->path() / "c/mav0/cam0/data" / first_image));
}

TEST(SequenceGeneratorOptionsTest, RefusesANonEmptyOutputFolderAndBadOptions) {
  ScratchDir dir("sequence_refuse");
  test::writeFile(dir / "keep.txt", "user data");
  SimulationOptions options = shortSequence(dir.path());
  EXPECT_THROW(generateSequence(options), InputError);
  EXPECT_EQ(test::readFile(dir / "keep.txt"), "user data");
  options.illumination.drift_amplitude = 2.0;
  EXPECT_THROW(generateSequence(options), OptionError);
}

}  // namespace
}  // namespace superdyna::sim

#include "commands/info_command.h"

#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "superdyna/core/error.h"
#include "superdyna/io/euroc_dataset.h"
#include "superdyna/io/kitti_dataset.h"
#ifdef SUPERDYNA_WITH_ROSBAG
#include "superdyna/bag/rosbag_reader.h"
#endif

namespace superdyna::apps {

namespace fs = std::filesystem;

namespace {

std::string describeRange(const TimeRange& range) {
  return fmt::format("{} .. {} s ({:.2f} s)", formatNsAsSeconds(range.begin),
                     formatNsAsSeconds(range.end), range.durationSeconds());
}

std::string describeCamera(const sensors::CameraCalibration& c) {
  std::string coefficients;
  for (double k : c.distortion)
    coefficients += fmt::format(" {:.6g}", k);
  const Eigen::Vector3d t = c.T_b_c.t;
  return fmt::format(
      "{}: {}x{} @ {} Hz, fx {:.3f} fy {:.3f} cx {:.3f} cy {:.3f}, {}{}, T_b_c t = ({:.4f}, "
      "{:.4f}, {:.4f}) m",
      c.name, c.width, c.height, c.rate_hz, c.fx, c.fy, c.cx, c.cy, toString(c.distortion_model),
      coefficients, t.x(), t.y(), t.z());
}

void printEuroc(const fs::path& path) {
  const io::EurocDataset d = io::EurocDataset::open(path);
  fmt::print("EuRoC sequence {}\n", d.root().string());
  fmt::print("  {}\n", describeCamera(d.cam0Calibration()));
  if (d.cam1Calibration()) fmt::print("  {}\n", describeCamera(*d.cam1Calibration()));
  fmt::print("  cam0 frames: {}, {}\n", d.monoFrames().size(), describeRange(d.cam0TimeRange()));
  if (d.isStereo()) fmt::print("  stereo pairs: {}\n", d.stereoFrames().size());
  if (const auto& imu = d.imuCalibration()) {
    fmt::print(
        "  imu0: {} samples, {}; {} Hz, gyro {:.4e} rad/s/sqrt(Hz) (walk {:.4e}), accel "
        "{:.4e} m/s^2/sqrt(Hz) (walk {:.4e}), T_b_i t = ({:.4f}, {:.4f}, {:.4f}) m, turned "
        "{:.2f} deg\n",
        d.imu().size(), describeRange(*d.imuTimeRange()), imu->rate_hz,
        imu->gyroscope_noise_density, imu->gyroscope_random_walk, imu->accelerometer_noise_density,
        imu->accelerometer_random_walk, imu->T_b_i.t.x(), imu->T_b_i.t.y(), imu->T_b_i.t.z(),
        imu->T_b_i.q.angularDistance(Eigen::Quaterniond::Identity()) * 180.0 / M_PI);
    fmt::print("  stereo pairs the IMU covers: {}\n", d.framesWithImuCoverage().size());
  }
  if (d.hasGroundTruth()) {
    fmt::print("  ground truth: {} states, {}{}\n", d.groundTruth().size(),
               describeRange(*d.groundTruthTimeRange()),
               d.groundTruthHasVelocityAndBiases() ? " (pose, velocity, biases)" : " (pose)");
  }
  for (const std::string& warning : d.warnings())
    fmt::print("  warning: {}\n", warning);
}

void printKitti(const fs::path& path) {
  const io::KittiDataset d = io::KittiDataset::open(path);
  fmt::print("KITTI sequence {}\n", d.root().string());
  fmt::print("  {}\n", describeCamera(d.leftCalibration()));
  if (const auto baseline = d.baseline()) fmt::print("  stereo baseline: {:.4f} m\n", *baseline);
  fmt::print("  frames: {} ({}), {}\n", d.size(), d.isStereo() ? "stereo" : "mono",
             describeRange(d.timeRange()));
  if (d.hasGroundTruth()) fmt::print("  ground truth: {} poses\n", d.groundTruth().size());
  for (const std::string& warning : d.warnings())
    fmt::print("  warning: {}\n", warning);
}

void printBag(const fs::path& path) {
#ifdef SUPERDYNA_WITH_ROSBAG
  const bag::RosbagReader reader = bag::RosbagReader::open(path);
  fmt::print("ROS bag {}: {} topics\n", path.string(), reader.topics().size());
  for (const bag::BagTopic& topic : reader.topics())
    fmt::print("  {}  {}  {} messages\n", topic.name, topic.type, topic.messages);
#else
  throw InputError(InputLocation{path},
                   "this build has no ROS bag support: install Debian's librosbag-storage-dev and "
                   "libsensor-msgs-dev and build again (scripts/setup.sh does both)");
#endif
}

class InfoCommand : public Command {
 public:
  explicit InfoCommand(CLI::App& app) {
    sub_ = app.add_subcommand(
        "info",
        "Read and validate a dataset folder and summarise its streams and calibration, or list "
        "the topics of a ROS 1 bag (--dataset rosbag)");
    addDatasetOptions(*sub_, kind_, path_, /*bags=*/true);
  }

  CLI::App* subcommand() const override { return sub_; }

  int run() override {
    if (kind_ == "kitti") {
      printKitti(path_);
    } else if (kind_ == "rosbag") {
      printBag(path_);
    } else {
      printEuroc(path_);
    }
    return 0;
  }

 private:
  CLI::App* sub_ = nullptr;
  std::string kind_ = "euroc";
  fs::path path_;
};

}  // namespace

std::unique_ptr<Command> makeInfoCommand(CLI::App& app) {
  return std::make_unique<InfoCommand>(app);
}

}  // namespace superdyna::apps

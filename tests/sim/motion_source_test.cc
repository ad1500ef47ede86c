#include "superdyna/sim/motion_source.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <iostream>
#include <map>
#include <vector>

#include "superdyna/sim/sequence_generator.h"
#include "support/test_support.h"

namespace superdyna::sim {
namespace {

namespace fs = std::filesystem;

constexpr const char* kTrajectories = "data/trajectories";

/// The convention `--motion-convention auto` must find for each shipped dataset's files.
const std::map<std::string, std::string>& expectedConventions() {
  static const std::map<std::string, std::string> conventions = {
      {"euroc", "body"},
      {"tum_vi", "tum-vi"},
      {"openloris", "forward-x"},
      {"kitti", "camera"},
  };
  return conventions;
}

bool isKittiTimesFile(const fs::path& file) {
  return file.stem().string().ends_with("_times");
}

/// Every trajectory file under data/trajectories/<dataset>/, sorted (times files excluded).
std::vector<fs::path> shippedTrajectories(const fs::path& root) {
  std::vector<fs::path> files;
  for (const auto& entry : fs::recursive_directory_iterator(root)) {
    if (entry.is_regular_file() && entry.path().extension() == ".txt" &&
        !isKittiTimesFile(entry.path())) {
      files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

/// The first `duration_s` of a shipped file, as the simulator reads it (KITTI with its times).
MotionSourceOptions shippedMotion(const fs::path& file, double duration_s) {
  MotionSourceOptions options;
  options.trajectory_file = file;
  const fs::path times = file.parent_path() / (file.stem().string() + "_times.txt");
  if (fs::exists(times)) options.read.kitti_times = times;
  options.duration_s = duration_s;
  return options;
}

std::string datasetOf(const fs::path& file) {
  return file.parent_path().filename().string();
}

/// How cam0 of the simulated rig points over a motion: the mean world-z component of its optical
/// axis (0 = level, 1 = straight at the sky) and of its image "up" direction (1 = upright).
struct CameraAttitude {
  double optical_axis_up = 0.0;
  double image_up_up = 0.0;
};

CameraAttitude cameraAttitude(const Trajectory& body_poses) {
  const SE3d T_b_c0 = RigOptions().T_b_c0();
  CameraAttitude attitude;
  for (const StampedPose& pose : body_poses) {
    const Eigen::Matrix3d R_w_c = (pose.T_w_x * T_b_c0).rotation();
    attitude.optical_axis_up += R_w_c(2, 2);
    attitude.image_up_up += -R_w_c(2, 1);  // image up = camera -y
  }
  attitude.optical_axis_up /= body_poses.size();
  attitude.image_up_up /= body_poses.size();
  return attitude;
}

TEST(MotionSource, EveryShippedTrajectoryKeepsItsCameraUprightAndOffTheSky) {
  SUPERDYNA_REQUIRE_SHARED(root, kTrajectories);
  const std::vector<fs::path> files = shippedTrajectories(root);
  ASSERT_GE(files.size(), 4u);
  for (const fs::path& file : files) {
    SCOPED_TRACE(file.string());
    const auto expected = expectedConventions().find(datasetOf(file));
    ASSERT_NE(expected, expectedConventions().end()) << "a dataset this test does not know";
    const MotionWindow motion = loadMotion(shippedMotion(file, 20.0), 25.0);
    EXPECT_EQ(toString(motion.convention), expected->second);
    const CameraAttitude attitude = cameraAttitude(motion.body_poses);
    std::cout << file.parent_path().filename().string() << "/" << file.filename().string() << " ("
              << toString(motion.convention) << "): mean world-z of cam0's optical axis "
              << attitude.optical_axis_up << ", of its image up " << attitude.image_up_up << "\n";
    // Level or looking down (EuRoC's drones look 20-35 degrees down), never at the sky.
    EXPECT_LT(attitude.optical_axis_up, 0.3);
    EXPECT_GT(attitude.optical_axis_up, -0.7);
    EXPECT_GT(attitude.image_up_up, 0.7);
  }
}

/// A quick, small rendering of a street scene along the first 20 s of a shipped file: a quarter
/// of the pixels, 2 frames per second.
SimulationOptions quickStreetSequence(const fs::path& file, const fs::path& out) {
  SimulationOptions options;
  options.output_dir = out;
  options.motion = shippedMotion(file, 20.0);
  options.world.scene = SceneType::kStreet;
  options.world.dynamic = DynamicLevel::kHigh;
  options.world.texel_scale = 2.0;
  options.rig.width = 376;
  options.rig.height = 240;
  options.rig.fx *= 0.5;
  options.rig.fy *= 0.5;
  options.rig.cx *= 0.5;
  options.rig.cy *= 0.5;
  options.rig.camera_rate_hz = 2.0;
  options.noise = false;
  options.landmark_count = 0;
  options.seed = 1;
  return options;
}

/// Renders one file of each shipped dataset (the test above checks the attitude along every
/// file): the camera must see the world's surfaces, not the sky, and the agents placed in view.
class ShippedMotionSees : public ::testing::TestWithParam<const char*> {};

TEST_P(ShippedMotionSees, TheSceneAndItsAgents) {
  SUPERDYNA_REQUIRE_SHARED(file, std::string(kTrajectories) + "/" + GetParam());
  const test::ScratchDir dir("motion_source_" + file.stem().string());
  const SimulationSummary summary = generateSequence(quickStreetSequence(file, dir / "seq"));
  std::cout << GetParam() << " (" << summary.frames << " frames): surfaces cover "
            << 100.0 * summary.mean_surface_coverage << " % of the image, agents "
            << 100.0 * summary.mean_agent_coverage << " %, " << summary.mean_moving_in_view
            << " moving agents in view\n";
  EXPECT_GT(summary.mean_surface_coverage, 0.7);
  EXPECT_GT(summary.mean_agent_coverage, 0.03);
  EXPECT_GT(summary.mean_moving_in_view, 1.0);
}

INSTANTIATE_TEST_SUITE_P(MotionSource, ShippedMotionSees,
                         ::testing::Values("euroc/MH_03_medium.txt", "tum_vi/room4.txt",
                                           "openloris/cafe_1.txt", "kitti/00.txt"),
                         [](const ::testing::TestParamInfo<const char*>& param) {
                           const std::string name = param.param;
                           return name.substr(0, name.find('/'));
                         });

}  // namespace
}  // namespace superdyna::sim

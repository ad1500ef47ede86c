#include "superdyna/system/system.h"

#include <gtest/gtest.h>

#include <string>

#include "superdyna/eval/evaluate.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/sim/sequence_generator.h"
#include "support/test_support.h"

namespace superdyna::system {
namespace {

namespace fs = std::filesystem;

// Measured (see the issue note): bounds with a wide margin over the measured ATE.
constexpr double kSyntheticAteBoundFraction = 0.005;  // of the path length
constexpr double kEurocAteBoundM = 0.005;

struct RunSummary {
  Trajectory trajectory;
  Trajectory ground_truth;
  std::size_t lost = 0;
  int resets = 0;
  bool inertial_initialized = false;
};

RunSummary runSlam(const fs::path& path, SensorMode mode) {
  io::DatasetSourceOptions source_options;
  source_options.inertial = usesImu(mode);
  const auto source = io::openDataset(io::DatasetKind::kEuroc, path, source_options);
  SystemOptions options;
  options.mode = mode;
  System slam(options, source->camera0(), *source->camera1(), source->imu());
  while (const auto frame = source->next())
    slam.process(*frame);
  return {slam.trajectory(), source->groundTruth(), slam.lostFrames(), slam.resets(),
          slam.inertialInitialized()};
}

eval::EvaluationResult ateOf(const RunSummary& run) {
  eval::EvaluationOptions options;
  options.align = eval::AlignmentMode::kSE3;
  options.rpe.unit = eval::DeltaUnit::kFrames;
  return eval::evaluate(run.ground_truth, run.trajectory, options);
}

/// An 8 s street flight with image and IMU noise, generated once for all tests here.
const fs::path& syntheticSequence() {
  static test::ScratchDir dir("system_test_street");
  static const bool generated = [] {
    sim::SimulationOptions options;
    options.output_dir = dir.path() / "seq";
    options.overwrite = true;
    options.motion.duration_s = 8.0;
    options.world.scene = sim::SceneType::kStreet;
    options.world.dynamic = sim::DynamicLevel::kNone;
    options.seed = 7;
    sim::generateSequence(options);
    return true;
  }();
  static const fs::path path = dir.path() / "seq";
  (void)generated;
  return path;
}

TEST(SensorMode, MonoModesAreNotImplementedYet) {
  EXPECT_EQ(parseSensorMode("stereo"), SensorMode::kStereo);
  EXPECT_EQ(parseSensorMode("stereo-inertial"), SensorMode::kStereoInertial);
  test::expectError<OptionError>([] { parseSensorMode("mono"); },
                                 {"not implemented yet", "stereo, stereo-inertial"});
  test::expectError<OptionError>([] { parseSensorMode("mono-inertial"); }, {"not implemented yet"});
  test::expectError<OptionError>([] { parseSensorMode("rgbd"); }, {"unknown mode"});
}

TEST(OptionsFile, SetsKnownKeysAndRejectsUnknownOnes) {
  const test::ScratchDir dir("system_options_file");
  test::writeFile(dir / "ok.yaml",
                  "orb:\n  features: 900\ntracker:\n  min_inliers: 20\nmapping:\n"
                  "  window_keyframes: 5\nprojection:\n  check_orientation: false\n");
  const SystemOptions options = loadSystemOptions(dir / "ok.yaml");
  EXPECT_EQ(options.front_end.orb.features, 900);
  EXPECT_EQ(options.tracker.min_inliers, 20);
  EXPECT_EQ(options.mapping.window_keyframes, 5);
  EXPECT_FALSE(options.tracker.projection.check_orientation);

  test::writeFile(dir / "bad_key.yaml", "tracker:\n  min_inlier: 20\n");
  test::expectError([&] { loadSystemOptions(dir / "bad_key.yaml"); },
                    {"bad_key.yaml", "tracker.min_inlier"});
  test::writeFile(dir / "bad_section.yaml", "trackr:\n  min_inliers: 20\n");
  test::expectError([&] { loadSystemOptions(dir / "bad_section.yaml"); },
                    {"bad_section.yaml", "trackr"});
  test::writeFile(dir / "bad_value.yaml", "mapping:\n  window_keyframes: 1\n");
  test::expectError([&] { loadSystemOptions(dir / "bad_value.yaml"); },
                    {"bad_value.yaml", "window_keyframes"});
}

TEST(ShippedConfigs, Load) {
  for (const char* name :
       {"euroc_stereo.yaml", "euroc_stereo_inertial.yaml", "kitti_stereo.yaml"}) {
    const fs::path file = fs::path(SUPERDYNA_SOURCE_DIR) / "configs" / name;
    EXPECT_NO_THROW(loadSystemOptions(file)) << file;
  }
}

TEST(StereoSlam, TracksSyntheticStreetWithinBound) {
  for (const SensorMode mode : {SensorMode::kStereo, SensorMode::kStereoInertial}) {
    const RunSummary run = runSlam(syntheticSequence(), mode);
    EXPECT_EQ(run.lost, 0u) << toString(mode);
    EXPECT_EQ(run.resets, 0) << toString(mode);
    const eval::EvaluationResult ate = ateOf(run);
    EXPECT_EQ(ate.pairs, run.trajectory.size());
    const double path = pathLength(run.ground_truth);
    std::cout << "synthetic street " << toString(mode) << ": ATE rmse " << ate.ate_trans.rmse
              << " m over " << path << " m path (" << 100.0 * ate.ate_trans.rmse / path << " %)\n";
    EXPECT_LT(ate.ate_trans.rmse, kSyntheticAteBoundFraction * path) << toString(mode);
    // 8 s of flight: the inertial initialisation (10 keyframes, >= 2 s) and its refinement ran.
    EXPECT_EQ(run.inertial_initialized, usesImu(mode)) << toString(mode);
  }
}

TEST(StereoSlam, IsDeterministic) {
  const RunSummary a = runSlam(syntheticSequence(), SensorMode::kStereoInertial);
  const RunSummary b = runSlam(syntheticSequence(), SensorMode::kStereoInertial);
  ASSERT_EQ(a.trajectory.size(), b.trajectory.size());
  for (std::size_t i = 0; i < a.trajectory.size(); ++i) {
    ASSERT_EQ(a.trajectory[i].t_ns, b.trajectory[i].t_ns);
    ASSERT_EQ(a.trajectory[i].T_w_x.t, b.trajectory[i].T_w_x.t) << "frame " << i;
    ASSERT_EQ(a.trajectory[i].T_w_x.q.coeffs(), b.trajectory[i].T_w_x.q.coeffs()) << "frame " << i;
  }
}

TEST(StereoSlam, RecoversFromLostTrackingWithANewMap) {
  io::DatasetSourceOptions source_options;
  source_options.max_frames = 60;
  const auto source = io::openDataset(io::DatasetKind::kEuroc, syntheticSequence(), source_options);
  SystemOptions options;
  options.mode = SensorMode::kStereoInertial;
  System slam(options, source->camera0(), *source->camera1(), source->imu());
  std::size_t lost = 0;
  while (auto frame = source->next()) {
    if (frame->index >= 20 && frame->index < 23) {  // three black frames
      frame->image0.setTo(0);
      frame->image1.setTo(0);
    }
    const tracking::TrackingResult result = slam.process(*frame);
    if (result.state == tracking::TrackingState::kLost) ++lost;
    EXPECT_TRUE(result.T_w_b.t.allFinite());
  }
  EXPECT_EQ(slam.trajectory().size(), 60u);
  EXPECT_GE(lost, 1u);
  EXPECT_LE(lost, 4u);
  EXPECT_EQ(slam.resets(), 1);
  EXPECT_GT(slam.numMapPoints(), 100u);
}

TEST(StereoSlam, TracksEurocExcerpt) {
  SUPERDYNA_REQUIRE_SHARED(path, "data/euroc/V1_01_easy_micro");
  for (const SensorMode mode : {SensorMode::kStereo, SensorMode::kStereoInertial}) {
    const RunSummary run = runSlam(path, mode);
    EXPECT_EQ(run.trajectory.size(), 95u);
    EXPECT_EQ(run.lost, 0u);
    const eval::EvaluationResult ate = ateOf(run);
    std::cout << "EuRoC V1_01_easy_micro " << toString(mode) << ": ATE rmse " << ate.ate_trans.rmse
              << " m\n";
    EXPECT_LT(ate.ate_trans.rmse, kEurocAteBoundM);
    // A stationary start (rotors vibrating): the guarded initialisation still runs, and the
    // visual-inertial tracking after it keeps the ATE.
    EXPECT_EQ(run.inertial_initialized, usesImu(mode)) << toString(mode);
  }
}

}  // namespace
}  // namespace superdyna::system

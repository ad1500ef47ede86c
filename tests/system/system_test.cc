#include "superdyna/system/system.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <iostream>
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
constexpr double kLearnedAteBoundFraction = 0.01;  // learned features, short runs

struct RunSummary {
  Trajectory trajectory;
  Trajectory ground_truth;
  std::size_t lost = 0;
  int resets = 0;
  MatchCounts matches;
};

RunSummary runSlam(const fs::path& path, SensorMode mode, SystemOptions options = {},
                   io::DatasetSourceOptions source_options = {}) {
  source_options.inertial = usesImu(mode);
  const auto source = io::openDataset(io::DatasetKind::kEuroc, path, source_options);
  options.mode = mode;
  System slam(options, source->camera0(), *source->camera1(), source->imu());
  while (const auto frame = source->next())
    slam.process(*frame);
  return {slam.trajectory(), source->groundTruth(), slam.lostFrames(), slam.resets(),
          slam.timings().matches};
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

/// A 3 s street flight among moving vehicles and pedestrians, with instance masks.
const fs::path& dynamicSequence() {
  static test::ScratchDir dir("system_test_dynamic");
  static const bool generated = [] {
    sim::SimulationOptions options;
    options.output_dir = dir.path() / "seq";
    options.overwrite = true;
    options.motion.duration_s = 3.0;
    options.world.scene = sim::SceneType::kStreet;
    options.world.dynamic = sim::DynamicLevel::kMid;
    options.landmark_count = 0;
    options.seed = 2;
    sim::generateSequence(options);
    return true;
  }();
  static const fs::path path = dir.path() / "seq";
  (void)generated;
  return path;
}

/// A 2 s indoor flight (static scene): the learned-feature runs are slow, so they get a short
/// sequence of their own.
const fs::path& indoorSequence() {
  static test::ScratchDir dir("system_test_indoor");
  static const bool generated = [] {
    sim::SimulationOptions options;
    options.output_dir = dir.path() / "seq";
    options.overwrite = true;
    options.motion.duration_s = 2.0;
    options.world.scene = sim::SceneType::kIndoor;
    options.world.dynamic = sim::DynamicLevel::kNone;
    options.landmark_count = 0;
    options.seed = 3;
    sim::generateSequence(options);
    return true;
  }();
  static const fs::path path = dir.path() / "seq";
  (void)generated;
  return path;
}

/// The shipped options file `name` under configs/.
SystemOptions shippedOptions(const std::string& name) {
  return loadSystemOptions(fs::path(SUPERDYNA_SOURCE_DIR) / "configs" / name);
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
  EXPECT_EQ(options.front_end.features.orb.features, 900);
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

TEST(OptionsFile, ReadsTheFeaturesSection) {
  const test::ScratchDir dir("system_options_features");
  test::writeFile(dir / "xfeat.yaml",
                  "features:\n  type: xfeat\n  model: exports/x.onnx\n  max_keypoints: 800\n"
                  "  class_wise_matching: false\nstereo:\n  max_l2_distance: 0.7\n"
                  "projection:\n  max_l2_distance: 0.8\n");
  const SystemOptions options = loadSystemOptions(dir / "xfeat.yaml");
  EXPECT_EQ(options.front_end.features.type, features::FeatureType::kXFeat);
  EXPECT_EQ(options.front_end.features.model, "exports/x.onnx");
  EXPECT_EQ(options.front_end.features.max_keypoints, 800);
  EXPECT_FALSE(options.front_end.features.class_wise_matching);
  EXPECT_EQ(options.front_end.stereo.max_l2_distance, 0.7);
  EXPECT_EQ(options.tracker.projection.max_l2_distance, 0.8);

  test::writeFile(dir / "bad_type.yaml", "features:\n  type: sift\n");
  test::expectError([&] { loadSystemOptions(dir / "bad_type.yaml"); },
                    {"bad_type.yaml", "features.type", "sift"});
  test::writeFile(dir / "bad_key.yaml", "features:\n  budget: 10\n");
  test::expectError([&] { loadSystemOptions(dir / "bad_key.yaml"); },
                    {"bad_key.yaml", "features.budget"});
  test::writeFile(dir / "bad_value.yaml", "features:\n  max_keypoints: 0\n");
  test::expectError([&] { loadSystemOptions(dir / "bad_value.yaml"); },
                    {"bad_value.yaml", "features.max_keypoints"});
}

TEST(ShippedConfigs, Load) {
  for (const char* name : {"euroc_stereo.yaml", "euroc_stereo_inertial.yaml", "kitti_stereo.yaml",
                           "euroc_stereo_inertial_xfeat.yaml"}) {
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
  }
}

TEST(ClassWiseMatching, NoCrossClassMatchesWhenOnSomeWhenOff) {
  io::DatasetSourceOptions source_options;
  source_options.instance_masks = true;
  SystemOptions options;
  options.front_end.features.class_wise_matching = true;
  const RunSummary on =
      runSlam(dynamicSequence(), SensorMode::kStereoInertial, options, source_options);
  options.front_end.features.class_wise_matching = false;
  const RunSummary off =
      runSlam(dynamicSequence(), SensorMode::kStereoInertial, options, source_options);
  std::cout << "dynamic street, 3 s: cross-class stereo / map-to-frame matches: class-wise on "
            << on.matches.stereo_cross_class << " / " << on.matches.map_cross_class << " of "
            << on.matches.stereo << " / " << on.matches.map << ", off "
            << off.matches.stereo_cross_class << " / " << off.matches.map_cross_class << " of "
            << off.matches.stereo << " / " << off.matches.map << "\n";
  EXPECT_GT(on.matches.stereo, 10000);
  EXPECT_GT(on.matches.map, 5000);
  EXPECT_EQ(on.matches.stereo_cross_class, 0);
  EXPECT_EQ(on.matches.map_cross_class, 0);
  EXPECT_GT(off.matches.stereo_cross_class, 0);
  EXPECT_GT(off.matches.map_cross_class, 0);
  // Without masks every keypoint is background: nothing can cross classes.
  const RunSummary unlabelled = runSlam(dynamicSequence(), SensorMode::kStereo, options,
                                        io::DatasetSourceOptions{.max_frames = 10});
  EXPECT_GT(unlabelled.matches.stereo, 1000);
  EXPECT_EQ(unlabelled.matches.stereo_cross_class, 0);
  EXPECT_EQ(unlabelled.matches.map_cross_class, 0);
}

bool havePythonOnnx() {
  return std::system("/usr/bin/python3 -c 'import onnx' >/dev/null 2>&1") == 0;
}

/// Runs stereo-inertial SLAM on the indoor sequence with the XFeat options and the given
/// extractor; expects no lost frame and an ATE within kLearnedAteBoundFraction of the path.
void expectLearnedSlamTracks(features::FeatureType type, const fs::path& model) {
  SystemOptions options = shippedOptions("euroc_stereo_inertial_xfeat.yaml");
  options.front_end.features.type = type;
  options.front_end.features.model = model.string();
  const RunSummary run = runSlam(indoorSequence(), SensorMode::kStereoInertial, options);
  EXPECT_EQ(run.lost, 0u);
  const eval::EvaluationResult ate = ateOf(run);
  const double path = pathLength(run.ground_truth);
  std::cout << features::toString(type) << " (" << model.filename().string()
            << "), synthetic indoor scene, 2 s, stereo-inertial: ATE rmse " << ate.ate_trans.rmse
            << " m over " << path << " m\n";
  EXPECT_LT(ate.ate_trans.rmse, kLearnedAteBoundFraction * path);
}

// One test for both learned extractors: the indoor sequence is generated once per process.
TEST(LearnedSlam, XFeatAndSuperPointContractModelRunTheWholePipeline) {
  SUPERDYNA_REQUIRE_SHARED(xfeat, "models/xfeat.onnx");
  expectLearnedSlamTracks(features::FeatureType::kXFeat, xfeat);
  if (!havePythonOnnx()) {
    GTEST_SKIP() << "SuperPoint part skipped: Debian's python3-onnx is not installed "
                    "(apt-get install python3-onnx)";
  }
  const test::ScratchDir dir("system_superpoint");
  const fs::path model = dir / "superpoint_xfeat.onnx";
  const std::string command = std::string("/usr/bin/python3 ") + SUPERDYNA_SOURCE_DIR +
                              "/scripts/make_superpoint_from_xfeat.py from-xfeat --xfeat " +
                              xfeat.string() + " --out " + model.string() + " >/dev/null";
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  expectLearnedSlamTracks(features::FeatureType::kSuperPoint, model);
}

}  // namespace
}  // namespace superdyna::system

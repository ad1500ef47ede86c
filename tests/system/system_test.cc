#include "superdyna/system/system.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "superdyna/eval/evaluate.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/sim/sequence_generator.h"
#include "superdyna/system/frame_log.h"
#include "support/generated_sequence.h"
#include "support/test_support.h"

namespace superdyna::system {
namespace {

namespace fs = std::filesystem;

// Measured (see the issue note): bounds with a wide margin over the measured ATE.
constexpr double kSyntheticAteBoundFraction = 0.005;  // of the path length
constexpr double kEurocAteBoundM = 0.005;
constexpr double kMonoSim3AteBoundFraction = 0.02;
constexpr double kLearnedAteBoundFraction = 0.01;  // learned features, short runs

struct RunSummary {
  Trajectory trajectory;
  Trajectory ground_truth;
  std::size_t lost = 0;
  int resets = 0;
  std::size_t frames = 0;
  bool inertial_initialized = false;
  MatchCounts matches;
  std::size_t initializing = 0;  ///< Monocular: frames spent initialising maps.
  std::size_t map_points = 0;    ///< Of the final map.
  std::size_t cross_class_map_points = 0;
};

RunSummary runSlam(const fs::path& path, SensorMode mode, SystemOptions options = {},
                   io::DatasetSourceOptions source_options = {}) {
  source_options.inertial = usesImu(mode);
  source_options.stereo = !isMonocular(mode);
  const auto source = io::openDataset(io::DatasetKind::kEuroc, path, source_options);
  options.mode = mode;
  System slam(options, source->camera0(), source->camera1(), source->imu());
  while (const auto frame = source->next())
    slam.process(*frame);
  return {slam.trajectory(),      source->groundTruth(),
          slam.lostFrames(),      slam.resets(),
          slam.timings().frames,  slam.inertialInitialized(),
          slam.timings().matches, slam.initializingFrames(),
          slam.numMapPoints(),    slam.numCrossClassMapPoints()};
}

/// The trajectory and ground truth of a finished run (for ateOf).
RunSummary summaryOf(const System& slam, const io::DatasetSource& source) {
  RunSummary run;
  run.trajectory = slam.trajectory();
  run.ground_truth = source.groundTruth();
  return run;
}

/// A dataset source that serves the frames of another one and fails at frame `fail_at`.
class FailingSource final : public io::DatasetSource {
 public:
  FailingSource(std::unique_ptr<io::DatasetSource> source, std::size_t fail_at)
      : source_(std::move(source)), fail_at_(fail_at) {}
  std::optional<sensors::FrameBundle> next() override {
    if (served_ == fail_at_) throw InputError(InputLocation{"frame.png"}, "unreadable image");
    ++served_;
    return source_->next();
  }
  std::size_t size() const override { return source_->size(); }
  const sensors::CameraCalibration& camera0() const override { return source_->camera0(); }
  const std::optional<sensors::CameraCalibration>& camera1() const override {
    return source_->camera1();
  }
  const std::optional<sensors::ImuCalibration>& imu() const override { return source_->imu(); }
  Trajectory groundTruth() const override { return source_->groundTruth(); }
  const std::vector<std::string>& warnings() const override { return source_->warnings(); }

 private:
  std::unique_ptr<io::DatasetSource> source_;
  std::size_t fail_at_;
  std::size_t served_ = 0;
};

eval::EvaluationResult ateOf(const RunSummary& run,
                             eval::AlignmentMode align = eval::AlignmentMode::kSE3) {
  eval::EvaluationOptions options;
  options.align = align;
  options.rpe.unit = eval::DeltaUnit::kFrames;
  return eval::evaluate(run.ground_truth, run.trajectory, options);
}

/// An 8 s street flight with image and IMU noise, generated once for all tests here.
const fs::path& syntheticSequence() {
  return test::generatedSequence(
      "system_test_street",
      test::flightOptions(8.0, sim::SceneType::kStreet, sim::DynamicLevel::kNone, 7));
}

/// A 3 s street flight among moving vehicles and pedestrians, with instance masks.
const fs::path& dynamicSequence() {
  sim::SimulationOptions options =
      test::flightOptions(3.0, sim::SceneType::kStreet, sim::DynamicLevel::kMid, 2);
  options.landmark_count = 0;
  return test::generatedSequence("system_test_dynamic", options);
}

/// A 2 s indoor flight (static scene): the learned-feature runs are slow, so they get a short
/// sequence of their own.
const fs::path& indoorSequence() {
  sim::SimulationOptions options =
      test::flightOptions(2.0, sim::SceneType::kIndoor, sim::DynamicLevel::kNone, 3);
  options.landmark_count = 0;
  return test::generatedSequence("system_test_indoor", options);
}

/// The shipped options file `name` under configs/.
SystemOptions shippedOptions(const std::string& name) {
  return loadSystemOptions(fs::path(SUPERDYNA_SOURCE_DIR) / "configs" / name);
}

TEST(SensorMode, ParsesAllFourModes) {
  EXPECT_EQ(parseSensorMode("stereo"), SensorMode::kStereo);
  EXPECT_EQ(parseSensorMode("stereo-inertial"), SensorMode::kStereoInertial);
  EXPECT_EQ(parseSensorMode("mono"), SensorMode::kMono);
  EXPECT_EQ(parseSensorMode("mono-inertial"), SensorMode::kMonoInertial);
  for (const SensorMode mode : {SensorMode::kStereo, SensorMode::kStereoInertial, SensorMode::kMono,
                                SensorMode::kMonoInertial}) {
    EXPECT_EQ(parseSensorMode(toString(mode)), mode);
  }
  EXPECT_TRUE(isMonocular(SensorMode::kMonoInertial));
  EXPECT_TRUE(usesImu(SensorMode::kMonoInertial));
  EXPECT_FALSE(usesImu(SensorMode::kMono));
  test::expectError<OptionError>([] { parseSensorMode("rgbd"); },
                                 {"unknown mode", "stereo, stereo-inertial, mono, mono-inertial"});
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

  test::writeFile(dir / "reference.yaml",
                  "tracker:\n  reference_matching: false\n  reference_min_inliers: 40\n"
                  "  reference_search_radius_px: 4\n  reference_ratio: 0.7\n");
  const SystemOptions reference = loadSystemOptions(dir / "reference.yaml");
  EXPECT_FALSE(reference.tracker.reference_matching.enabled);
  EXPECT_EQ(reference.tracker.reference_matching.min_inliers, 40);
  EXPECT_EQ(reference.tracker.reference_matching.search_radius_px, 4.0);
  EXPECT_EQ(reference.tracker.reference_matching.matching.ratio, 0.7);
  test::writeFile(dir / "bad_reference.yaml", "tracker:\n  reference_min_inliers: 2\n");
  test::expectError([&] { loadSystemOptions(dir / "bad_reference.yaml"); },
                    {"bad_reference.yaml", "tracker.reference_min_inliers"});
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
  std::size_t loaded = 0;
  for (const auto& entry : fs::directory_iterator(fs::path(SUPERDYNA_SOURCE_DIR) / "configs")) {
    if (entry.path().extension() != ".yaml") continue;
    EXPECT_NO_THROW(loadSystemOptions(entry.path())) << entry.path();
    ++loaded;
  }
  EXPECT_GE(loaded, 12u);
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

struct BlackoutRun {
  std::size_t lost = 0;
  std::size_t relocalized = 0;
  int resets = 0;
  std::size_t trajectory_size = 0;
  std::size_t map_points = 0;
};

/// Stereo-inertial over 60 frames of the street flight with three black frames at 1 s (before the
/// inertial initialisation: no IMU bridge).
BlackoutRun runWithBlackFramesBeforeInertialInit(double relocalization_s) {
  io::DatasetSourceOptions source_options;
  source_options.max_frames = 60;
  const auto source = io::openDataset(io::DatasetKind::kEuroc, syntheticSequence(), source_options);
  SystemOptions options;
  options.mode = SensorMode::kStereoInertial;
  options.tracker.relocalization_s = relocalization_s;
  System slam(options, source->camera0(), *source->camera1(), source->imu());
  BlackoutRun run;
  while (auto frame = source->next()) {
    if (frame->index >= 20 && frame->index < 23) {  // three black frames
      frame->image0.setTo(0);
      frame->image1.setTo(0);
    }
    const tracking::TrackingResult result = slam.process(*frame);
    if (result.state == tracking::TrackingState::kLost) ++run.lost;
    if (result.relocalized) ++run.relocalized;
    EXPECT_TRUE(result.T_w_b.t.allFinite());
  }
  EXPECT_EQ(static_cast<int>(run.relocalized), slam.relocalizations());
  run.resets = slam.resets();
  run.trajectory_size = slam.trajectory().size();
  run.map_points = slam.numMapPoints();
  return run;
}

TEST(StereoSlam, KeepsItsMapThroughABlackoutUnlessRelocalisationIsOff) {
  const BlackoutRun kept = runWithBlackFramesBeforeInertialInit(3.0);
  const BlackoutRun reset = runWithBlackFramesBeforeInertialInit(0.0);
  for (const BlackoutRun* run : {&kept, &reset}) {
    EXPECT_EQ(run->trajectory_size, 60u);
    EXPECT_EQ(run->relocalized, 0u);
    EXPECT_GT(run->map_points, 100u);
  }
  // The black frames only: the map is kept, and the frame after them is tracked in it from the
  // prediction (0.15 s of constant velocity is close enough: no relocalisation needed).
  EXPECT_EQ(kept.lost, 3u);
  EXPECT_EQ(kept.resets, 0);
  // Without the relocalisation window the first failure starts a new map (the old behaviour).
  EXPECT_GE(reset.lost, 1u);
  EXPECT_LE(reset.lost, 4u);
  EXPECT_EQ(reset.resets, 1);
}

TEST(FrameLog, WritesOneRowPerFrameWithTheTrackerState) {
  const test::ScratchDir scratch("frame_log_test");
  io::DatasetSourceOptions source_options;
  source_options.max_frames = 30;
  const auto source = io::openDataset(io::DatasetKind::kEuroc, syntheticSequence(), source_options);
  SystemOptions options;
  options.deterministic = true;
  System slam(options, source->camera0(), *source->camera1(), source->imu());
  {
    FrameLog log(scratch / "frames.csv", "--frame-log");
    slam.run(*source, [&](const tracking::TrackingResult& result) {
      log.write(slam.timings().frames - 1, result);
    });
  }
  std::ifstream in(scratch / "frames.csv");
  std::vector<std::string> rows;
  for (std::string line; std::getline(in, line);)
    rows.push_back(line);
  ASSERT_EQ(rows.size(), 31u);
  EXPECT_EQ(rows[0], "frame,state,matches,inliers,prediction_m,from_reference,keyframe,recovered");
  EXPECT_EQ(rows[1], "0,initialized,0,0,,0,1,");
  // The second frame of a map has no motion model: tracked from the reference keyframe.
  EXPECT_EQ(rows[2].substr(0, 11), "1,tracking,");
  EXPECT_EQ(rows[2].substr(rows[2].size() - 5, 2), ",1");
  std::size_t keyframes = 0;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i].substr(0, rows[i].find(',')), std::to_string(i - 1));
    ASSERT_GE(rows[i].size(), 3u);
    EXPECT_EQ(rows[i].back(), ',') << rows[i];  // nothing to recover from
    keyframes += rows[i][rows[i].size() - 2] == '1' ? 1 : 0;
  }
  EXPECT_EQ(keyframes, slam.timings().keyframes);
  EXPECT_EQ(slam.referenceTrackedFrames(), 1u);
  test::expectError<OptionError>(
      [&] { FrameLog bad(scratch / "missing" / "frames.csv", "--frame-log"); },
      {"--frame-log", "cannot open"});
}

struct BridgedRun {
  std::size_t recently_lost = 0;
  std::size_t lost = 0;
  int resets = 0;
  bool initialized_before_gap = false;
  RunSummary summary;
};

/// Stereo-inertial over the first 4 s of the street flight with three black frames at 3 s (after
/// the inertial initialisation).
BridgedRun runWithBlackFramesAfterInertialInit(double imu_bridge_s, double relocalization_s) {
  io::DatasetSourceOptions source_options;
  source_options.max_frames = 80;
  const auto source = io::openDataset(io::DatasetKind::kEuroc, syntheticSequence(), source_options);
  SystemOptions options;
  options.mode = SensorMode::kStereoInertial;
  options.tracker.imu_bridge_s = imu_bridge_s;
  options.tracker.relocalization_s = relocalization_s;
  System slam(options, source->camera0(), *source->camera1(), source->imu());
  BridgedRun run;
  while (auto frame = source->next()) {
    if (frame->index == 60) run.initialized_before_gap = slam.inertialInitialized();
    if (frame->index >= 60 && frame->index < 63) {
      frame->image0.setTo(0);
      frame->image1.setTo(0);
    }
    const tracking::TrackingResult result = slam.process(*frame);
    if (result.state == tracking::TrackingState::kRecentlyLost) ++run.recently_lost;
    if (result.state == tracking::TrackingState::kLost) ++run.lost;
  }
  run.resets = slam.resets();
  run.summary = summaryOf(slam, *source);
  EXPECT_EQ(slam.lostFrames(), run.lost + run.recently_lost);
  return run;
}

TEST(StereoInertialSlam, BridgesAShortTrackingFailureWithTheImu) {
  const BridgedRun bridged = runWithBlackFramesAfterInertialInit(3.0, 0.0);
  ASSERT_TRUE(bridged.initialized_before_gap);
  EXPECT_EQ(bridged.recently_lost, 3u);  // the IMU prediction, then tracking on the same map
  EXPECT_EQ(bridged.lost, 0u);
  EXPECT_EQ(bridged.resets, 0);
  const double path = pathLength(bridged.summary.ground_truth);
  EXPECT_LT(ateOf(bridged.summary).ate_trans.rmse, kSyntheticAteBoundFraction * path);
  // A bridge shorter than the gap (0.1 s: two of the three black frames) ends in a new map
  // without relocalisation.
  const BridgedRun short_bridge = runWithBlackFramesAfterInertialInit(0.1, 0.0);
  EXPECT_EQ(short_bridge.recently_lost, 2u);
  EXPECT_GE(short_bridge.lost, 1u);
  EXPECT_EQ(short_bridge.resets, 1);
}

/// A copy of `sequence` in `dir` (images hard-linked) whose imu0/data.csv lacks the rows from
/// gap_start_s to gap_end_s after its first row, as when a real IMU stream drops out.
fs::path copyWithImuGap(const fs::path& sequence, const fs::path& dir, double gap_start_s,
                        double gap_end_s) {
  const fs::path copy = dir / "seq";
  fs::copy(sequence, copy, fs::copy_options::recursive | fs::copy_options::create_hard_links);
  const fs::path csv = copy / "mav0" / "imu0" / "data.csv";
  std::ifstream in(sequence / "mav0" / "imu0" / "data.csv");
  fs::remove(csv);  // a hard link to the original: write a new file
  std::ofstream out(csv);
  std::string line;
  std::optional<TimeNs> first;
  while (std::getline(in, line)) {
    if (!line.empty() && line.front() != '#') {
      const TimeNs t = std::stoll(line.substr(0, line.find(',')));
      if (!first) first = t;
      const double since_s = nsToSeconds(t - *first);
      if (since_s >= gap_start_s && since_s < gap_end_s) continue;
    }
    out << line << '\n';
  }
  return copy;
}

/// Stereo-inertial over the first 5.5 s of the street flight whose IMU has no samples from 3 to
/// 4 s (after the inertial initialisation).
TEST(StereoInertialSlam, TracksThroughAOneSecondImuGap) {
  const test::ScratchDir dir("system_test_imu_gap");
  const fs::path gapped = copyWithImuGap(syntheticSequence(), dir.path(), 3.0, 4.0);
  io::DatasetSourceOptions source_options;
  source_options.max_frames = 110;
  const auto source = io::openDataset(io::DatasetKind::kEuroc, gapped, source_options);
  SystemOptions options;
  options.mode = SensorMode::kStereoInertial;
  System slam(options, source->camera0(), source->camera1(), source->imu());
  std::vector<tracking::ImuGap> gaps;
  bool initialized_before_gap = false;
  while (const auto frame = source->next()) {
    if (frame->index == 60) initialized_before_gap = slam.inertialInitialized();
    const tracking::TrackingResult result = slam.process(*frame);
    if (result.imu_gap) gaps.push_back(*result.imu_gap);
  }
  EXPECT_TRUE(initialized_before_gap);
  ASSERT_EQ(gaps.size(), 1u);  // reported once, though every frame in it meets it
  EXPECT_NEAR(gaps.front().seconds(), 1.005, 1e-6);  // 1 s of rows removed, 200 Hz
  EXPECT_EQ(slam.timings().frames, 110u);
  EXPECT_EQ(slam.lostFrames(), 0u);
  EXPECT_EQ(slam.resets(), 0);
  EXPECT_TRUE(slam.inertialInitialized());
  const RunSummary run = summaryOf(slam, *source);
  EXPECT_LT(ateOf(run).ate_trans.rmse, kSyntheticAteBoundFraction * pathLength(run.ground_truth));
}

/// syntheticSequence()'s flight (same body motion and images) with the IMU mounted 23 cm from the
/// body origin and turned by 81 deg: imu0/sensor.yaml's T_BS says where, and the IMU measures in
/// its own frame at its own origin.
sim::SimulationOptions offsetImuOptions() {
  sim::SimulationOptions options =
      test::flightOptions(8.0, sim::SceneType::kStreet, sim::DynamicLevel::kNone, 7);
  options.rig.imu_offset_m = Eigen::Vector3d(0.2, -0.1, 0.05);
  options.rig.imu_rotation_deg = Eigen::Vector3d(30.0, -60.0, 45.0);
  return options;
}

/// Stereo-inertial over the first 5 s of `path`, with the IMU pose in the body frame replaced by
/// `T_b_i` when given.
RunSummary runStereoInertialFiveSeconds(const fs::path& path,
                                        const std::optional<SE3d>& T_b_i = std::nullopt) {
  io::DatasetSourceOptions source_options;
  source_options.max_frames = 100;
  const auto source = io::openDataset(io::DatasetKind::kEuroc, path, source_options);
  std::optional<sensors::ImuCalibration> imu = source->imu();
  if (T_b_i) imu->T_b_i = *T_b_i;
  SystemOptions options;
  options.mode = SensorMode::kStereoInertial;
  System slam(options, source->camera0(), source->camera1(), imu);
  while (const auto frame = source->next())
    slam.process(*frame);
  RunSummary run = summaryOf(slam, *source);
  run.lost = slam.lostFrames();
  run.resets = slam.resets();
  run.inertial_initialized = slam.inertialInitialized();
  return run;
}

TEST(StereoInertialSlam, AnOffsetRotatedImuTracksAsWellAsOneAtTheBodyOrigin) {
  const sim::SimulationOptions options = offsetImuOptions();
  const fs::path& offset_path = test::generatedSequence("system_test_offset_imu", options);
  const auto source = io::openDataset(io::DatasetKind::kEuroc, offset_path, {});
  ASSERT_TRUE(source->imu());
  const SE3d T_b_i = options.rig.T_b_i();
  EXPECT_LT((source->imu()->T_b_i.t - T_b_i.t).norm(), 1e-9);
  EXPECT_LT(source->imu()->T_b_i.q.angularDistance(T_b_i.q), 1e-9);

  const RunSummary at_origin = runStereoInertialFiveSeconds(syntheticSequence());
  const RunSummary offset = runStereoInertialFiveSeconds(offset_path);
  const double ate_origin = ateOf(at_origin).ate_trans.rmse;
  const double ate_offset = ateOf(offset).ate_trans.rmse;
  const double path = pathLength(offset.ground_truth);
  std::cout << "synthetic street, first 5 s, stereo-inertial: ATE rmse " << ate_origin
            << " m with the IMU at the body origin, " << ate_offset << " m offset and turned ("
            << path << " m path)\n";
  EXPECT_TRUE(offset.inertial_initialized);
  EXPECT_EQ(offset.lost, 0u);
  EXPECT_EQ(offset.resets, 0);
  EXPECT_LT(ate_offset, kSyntheticAteBoundFraction * path);
  EXPECT_LT(ate_offset, 1.5 * ate_origin + 0.002);
}

/// A 3 s street flight (60 frames), cheaper to generate for the tests that need few frames.
const fs::path& shortSequence() {
  return test::generatedSequence(
      "system_test_short",
      test::flightOptions(3.0, sim::SceneType::kStreet, sim::DynamicLevel::kNone, 7));
}

std::unique_ptr<io::DatasetSource> openSynthetic(std::size_t max_frames = 0,
                                                 const fs::path& path = syntheticSequence()) {
  io::DatasetSourceOptions source_options;
  source_options.max_frames = max_frames;
  return io::openDataset(io::DatasetKind::kEuroc, path, source_options);
}

SystemOptions concurrentOptions() {
  SystemOptions options;
  options.mode = SensorMode::kStereoInertial;
  options.deterministic = false;
  return options;
}

/// Each keyframe time is a frame time, in order, and the keyframes are those tracking reported.
void expectKeyFramesMatchFrames(const System& slam) {
  const Trajectory keyframes = slam.keyFrameTrajectory();
  const Trajectory frames = slam.trajectory();
  EXPECT_EQ(keyframes.size(), slam.timings().keyframes);
  std::size_t frame = 0;
  for (const StampedPose& kf : keyframes) {
    while (frame < frames.size() && frames[frame].t_ns < kf.t_ns)
      ++frame;
    ASSERT_LT(frame, frames.size());
    EXPECT_EQ(frames[frame].t_ns, kf.t_ns);
    EXPECT_TRUE(kf.T_w_x.t.allFinite());
  }
}

/// The entry of `trajectory` at time t_ns (which must be there).
const StampedPose& poseAtTime(const Trajectory& trajectory, TimeNs t_ns) {
  const auto it = std::lower_bound(trajectory.begin(), trajectory.end(), t_ns,
                                   [](const StampedPose& pose, TimeNs t) { return pose.t_ns < t; });
  if (it == trajectory.end() || it->t_ns != t_ns) throw std::runtime_error("no pose at that time");
  return *it;
}

// As ORB-SLAM reports its frames: a frame's pose follows the later corrections (local BA) of the
// keyframe it was tracked against, so a keyframe's own frame ends at that keyframe's final pose
// and not at the pose tracking gave it.
TEST(StereoInertialSlam, FramesAreReportedThroughTheirKeyFramesFinalPoses) {
  const auto source = openSynthetic(60, shortSequence());
  SystemOptions options;
  options.mode = SensorMode::kStereoInertial;
  System slam(options, source->camera0(), *source->camera1(), source->imu());
  slam.run(*source);
  ASSERT_EQ(slam.resets(), 0);
  const Trajectory frames = slam.trajectory();
  const Trajectory online = slam.onlineTrajectory();
  ASSERT_EQ(frames.size(), online.size());
  double moved_m = 0.0;  // how far local BA moved the keyframes after tracking
  std::size_t keyframes = 0;
  for (const StampedPose& kf : slam.keyFrameTrajectory()) {
    const StampedPose& reported = poseAtTime(frames, kf.t_ns);
    EXPECT_LT((reported.T_w_x.t - kf.T_w_x.t).norm(), 1e-9);
    EXPECT_LT(reported.T_w_x.q.angularDistance(kf.T_w_x.q), 1e-9);
    moved_m = std::max(moved_m, (poseAtTime(online, kf.t_ns).T_w_x.t - kf.T_w_x.t).norm());
    ++keyframes;
  }
  EXPECT_GE(keyframes, 5u);
  EXPECT_GT(moved_m, 1e-4) << "local BA should have moved some keyframe after it was tracked";
}

TEST(StereoSlam, RunMatchesFrameByFrameProcessing) {
  const auto source_a = openSynthetic(40, shortSequence());
  SystemOptions options;
  options.mode = SensorMode::kStereoInertial;
  System a(options, source_a->camera0(), *source_a->camera1(), source_a->imu());
  std::size_t callbacks = 0;
  a.run(*source_a, [&](const tracking::TrackingResult&) { ++callbacks; });
  const auto source_b = openSynthetic(40, shortSequence());
  System b(options, source_b->camera0(), *source_b->camera1(), source_b->imu());
  while (const auto frame = source_b->next())
    b.process(*frame);
  EXPECT_EQ(callbacks, 40u);
  ASSERT_EQ(a.trajectory().size(), b.trajectory().size());
  for (std::size_t i = 0; i < a.trajectory().size(); ++i) {
    ASSERT_EQ(a.trajectory()[i].T_w_x.t, b.trajectory()[i].T_w_x.t) << "frame " << i;
  }
  expectKeyFramesMatchFrames(a);
  EXPECT_GT(a.timings().wall_s, 0.0);
  EXPECT_GT(a.timings().busy.front_end_ms, 0.0);
  EXPECT_EQ(a.timings().busy.mapping_ms, 0.0);  // no mapping thread
}

TEST(ConcurrentSlam, TracksSyntheticStreetWithinBound) {
  const auto source = openSynthetic();
  System slam(concurrentOptions(), source->camera0(), *source->camera1(), source->imu());
  slam.run(*source);
  EXPECT_EQ(slam.trajectory().size(), source->size());
  EXPECT_EQ(slam.lostFrames(), 0u);
  EXPECT_EQ(slam.resets(), 0);
  expectKeyFramesMatchFrames(slam);
  EXPECT_GT(slam.timings().busy.mapping_ms, 0.0);  // local BA ran in the mapping thread
  EXPECT_GT(slam.timings().busy.front_end_ms, 0.0);
  const eval::EvaluationResult ate = ateOf(summaryOf(slam, *source));
  const double path = pathLength(source->groundTruth());
  std::cout << "synthetic street concurrent: ATE rmse " << ate.ate_trans.rmse << " m ("
            << 100.0 * ate.ate_trans.rmse / path << " %)\n";
  EXPECT_LT(ate.ate_trans.rmse, kSyntheticAteBoundFraction * path);
}

TEST(ConcurrentSlam, RecoversFromLostTrackingWithANewMap) {
  const auto source = openSynthetic(60, shortSequence());
  SystemOptions options = concurrentOptions();
  options.tracker.relocalization_s = 0.0;  // relocalisation would keep the map
  System slam(options, source->camera0(), *source->camera1(), source->imu());
  std::size_t lost = 0;
  while (auto frame = source->next()) {
    if (frame->index >= 20 && frame->index < 23) {  // three black frames
      frame->image0.setTo(0);
      frame->image1.setTo(0);
    }
    if (slam.process(*frame).state == tracking::TrackingState::kLost) ++lost;
  }
  slam.finish();
  EXPECT_EQ(slam.trajectory().size(), 60u);
  EXPECT_GE(lost, 1u);
  EXPECT_LE(lost, 4u);
  EXPECT_EQ(slam.resets(), 1);
  EXPECT_GT(slam.numMapPoints(), 100u);
  expectKeyFramesMatchFrames(slam);  // keyframes of the dropped map are kept too
}

TEST(ConcurrentSlam, AFrontEndErrorEndsTheRun) {
  FailingSource source(openSynthetic(0, shortSequence()), 15);
  System slam(concurrentOptions(), source.camera0(), *source.camera1(), source.imu());
  test::expectError([&] { slam.run(source); }, {"frame.png", "unreadable image"});
  EXPECT_EQ(slam.trajectory().size(), 15u);  // every frame read before the error was tracked
}

TEST(ConcurrentSlam, ATrackingThreadErrorStopsTheFrontEnd) {
  const auto source = openSynthetic(0, shortSequence());
  System slam(concurrentOptions(), source->camera0(), *source->camera1(), source->imu());
  test::expectError<std::runtime_error>(
      [&] {
        slam.run(*source, [&](const tracking::TrackingResult&) {
          if (slam.trajectory().size() == 10) throw std::runtime_error("stop at frame 10");
        });
      },
      {"stop at frame 10"});
  EXPECT_EQ(slam.trajectory().size(), 10u);
}

TEST(MonoSlam, InitialisesAndTracksSyntheticStreet) {
  const RunSummary run = runSlam(syntheticSequence(), SensorMode::kMono);
  const std::size_t initializing = run.initializing;
  EXPECT_EQ(run.lost, 0u);
  EXPECT_EQ(run.resets, 0);
  EXPECT_LT(initializing, 30u);  // frames before the two-view initialisation succeeded
  EXPECT_EQ(run.trajectory.size() + initializing, run.frames);
  const eval::EvaluationResult ate = ateOf(run, eval::AlignmentMode::kSim3);
  const double path = pathLength(run.ground_truth);
  std::cout << "synthetic street mono: " << initializing << " frames initialising, ATE (Sim3) rmse "
            << ate.ate_trans.rmse << " m over " << path << " m path\n";
  EXPECT_LT(ate.ate_trans.rmse, kMonoSim3AteBoundFraction * path);
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

TEST(ClassWiseMatching, MonocularMapsHaveNoCrossClassPoints) {
  // Monocular maps grow only by the two-view initialisation and keyframe-to-keyframe
  // triangulation: both must respect the classes as the tracking does.
  io::DatasetSourceOptions source_options;
  source_options.instance_masks = true;
  for (const auto& [mode, config] :
       {std::pair{SensorMode::kMono, "euroc_mono.yaml"},
        std::pair{SensorMode::kMonoInertial, "euroc_mono_inertial.yaml"}}) {
    SystemOptions options = shippedOptions(config);
    options.front_end.features.class_wise_matching = true;
    const RunSummary on = runSlam(dynamicSequence(), mode, options, source_options);
    options.front_end.features.class_wise_matching = false;
    const RunSummary off = runSlam(dynamicSequence(), mode, options, source_options);
    std::cout << "dynamic street, 3 s, " << toString(mode)
              << ": cross-class map points: class-wise on " << on.cross_class_map_points << " of "
              << on.map_points << ", off " << off.cross_class_map_points << " of " << off.map_points
              << "\n";
    EXPECT_GT(on.map_points, 500u) << toString(mode);
    EXPECT_EQ(on.cross_class_map_points, 0u) << toString(mode);
    EXPECT_GT(off.cross_class_map_points, 0u) << toString(mode);
  }
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

// Tracking failures in the whole system: a 2 s blackout in the middle of an inertial run keeps
// the map (the IMU prediction, relocalisation, or a keyframe at the predicted pose bring the
// frames back into it) instead of starting a new one.

#include <gtest/gtest.h>

#include <functional>
#include <iostream>
#include <optional>
#include <string>

#include "superdyna/core/trajectory.h"
#include "superdyna/eval/evaluate.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/system/system.h"
#include "support/generated_sequence.h"
#include "support/test_support.h"

namespace superdyna::system {
namespace {

namespace fs = std::filesystem;

/// 14 s of the real EuRoC V2_02 motion (from its `start_s`th second) through the street scene:
/// `superdyna simulate --scene street --dynamic none --duration 14 --seed 21 --trajectory
/// V2_02_medium.txt --start START_S`. Blackouts are applied to the images as they are read.
fs::path streetSequence(const fs::path& motion, double start_s) {
  sim::SimulationOptions options =
      test::flightOptions(14.0, sim::SceneType::kStreet, sim::DynamicLevel::kNone, 21);
  options.motion.trajectory_file = motion;
  options.motion.start_s = start_s;
  return test::generatedSequence(
      "relocalization_test_street_" + std::to_string(static_cast<int>(start_s)), options);
}

struct BlackoutRun {
  double ate_m = 0.0;
  double path_m = 0.0;
  std::size_t poses = 0;
  std::size_t lost = 0;
  int resets = 0;
  int relocalizations = 0;
  int reanchors = 0;
};

/// The shipped configuration of `mode` (then `adjust`), deterministic, over the sequence; with a
/// blackout both images are black in its interval.
BlackoutRun runStreet(const fs::path& sequence, SensorMode mode, const std::string& config,
                      const std::optional<test::Blackout>& blackout,
                      const std::function<void(SystemOptions&)>& adjust = {}) {
  io::DatasetSourceOptions source_options;
  source_options.inertial = usesImu(mode);
  source_options.stereo = !isMonocular(mode);
  const auto source = io::openDataset(io::DatasetKind::kEuroc, sequence, source_options);
  SystemOptions options = loadSystemOptions(fs::path(SUPERDYNA_SOURCE_DIR) / "configs" / config);
  options.mode = mode;
  options.deterministic = true;
  if (adjust) adjust(options);
  System slam(options, source->camera0(), source->camera1(), source->imu());
  std::optional<TimeNs> t_first;
  while (auto frame = source->next()) {
    if (!t_first) t_first = frame->t_ns;
    if (blackout) blackout->apply(*frame, nsToSeconds(frame->t_ns - *t_first));
    slam.process(*frame);
  }
  eval::EvaluationOptions evaluation;
  evaluation.rpe.unit = eval::DeltaUnit::kFrames;
  const Trajectory trajectory = slam.trajectory();
  BlackoutRun run;
  run.ate_m = eval::evaluate(source->groundTruth(), trajectory, evaluation).ate_trans.rmse;
  run.path_m = pathLength(source->groundTruth());
  run.poses = trajectory.size();
  run.lost = slam.lostFrames();
  run.resets = slam.resets();
  run.relocalizations = slam.relocalizations();
  run.reanchors = slam.reanchors();
  std::cout << toString(mode) << (blackout ? ", 2 s blackout" : ", no blackout") << ": ATE rmse "
            << run.ate_m << " m over " << run.path_m << " m, " << run.poses << " poses, "
            << run.lost << " lost, " << run.resets << " resets, " << run.relocalizations
            << " relocalisations, " << run.reanchors << " keyframes at the IMU pose\n";
  return run;
}

/// The blackout costs 40 lost frames (2 s at 20 Hz) and nothing else: the run ends in the map it
/// started, and its ATE stays within 1.5 times that of the run without blackout (issue 11).
/// Without relocalisation (tracker.relocalization_s 0, the behaviour before) both modes started a
/// new map after the blackout: stereo-inertial 0.20 m against 2.5 mm, mono-inertial 0.47 m.
void expectResumesInItsMap(SensorMode mode, const std::string& config) {
  SUPERDYNA_REQUIRE_SHARED(motion, "data/trajectories/euroc/V2_02_medium.txt");
  const fs::path sequence = streetSequence(motion, 5.0);
  const BlackoutRun clean = runStreet(sequence, mode, config, std::nullopt);
  const BlackoutRun blackout = runStreet(sequence, mode, config, test::Blackout{9.0, 11.0});
  EXPECT_EQ(clean.lost, 0u);
  EXPECT_EQ(clean.resets, 0);
  EXPECT_EQ(blackout.lost, 40u);
  EXPECT_EQ(blackout.resets, 0);
  EXPECT_EQ(blackout.poses, clean.poses);
  EXPECT_LE(blackout.ate_m, 1.5 * clean.ate_m);
}

TEST(Relocalisation, StereoInertialResumesInItsMapAfterATwoSecondBlackout) {
  expectResumesInItsMap(SensorMode::kStereoInertial, "euroc_stereo_inertial.yaml");
}

TEST(Relocalisation, MonoInertialResumesInItsMapAfterATwoSecondBlackout) {
  expectResumesInItsMap(SensorMode::kMonoInertial, "euroc_mono_inertial.yaml");
}

/// V2_02 from its 17th second, black from 8 to 10 s: meanwhile the rig turns by about 60 degrees,
/// and the first frame after the blackout sees nothing its map holds (neither tracked from the IMU
/// prediction nor relocalised). Stereo-inertial then starts a keyframe at the IMU-predicted pose in
/// the same map (tracker.imu_reanchor); without it the frames wait out the relocalisation window
/// and a new map starts. Measured: 8.0 mm with the keyframe, 22.7 mm and one new map without (5.1
/// mm without blackout; 0.17 m with a new map at once, tracker.relocalization_s 0).
TEST(Relocalisation, StereoInertialContinuesItsMapFromTheImuWhenTheViewIsNew) {
  SUPERDYNA_REQUIRE_SHARED(motion, "data/trajectories/euroc/V2_02_medium.txt");
  const fs::path sequence = streetSequence(motion, 17.0);
  const test::Blackout blackout{8.0, 10.0};
  const BlackoutRun reanchored =
      runStreet(sequence, SensorMode::kStereoInertial, "euroc_stereo_inertial.yaml", blackout);
  const BlackoutRun waited =
      runStreet(sequence, SensorMode::kStereoInertial, "euroc_stereo_inertial.yaml", blackout,
                [](SystemOptions& options) { options.tracker.imu_reanchor = false; });
  EXPECT_EQ(reanchored.reanchors, 1);
  EXPECT_EQ(reanchored.resets, 0);
  EXPECT_EQ(reanchored.lost, 41u);  // the black frames and the keyframe at the IMU pose
  EXPECT_EQ(waited.reanchors, 0);
  EXPECT_EQ(waited.resets, 1);
  EXPECT_GT(waited.lost, 41u);
  EXPECT_LT(reanchored.ate_m, 0.5 * waited.ate_m);
  EXPECT_LT(reanchored.ate_m, 0.002 * reanchored.path_m);
}

}  // namespace
}  // namespace superdyna::system

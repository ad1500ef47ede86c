// Loop closing in the whole system: a short indoor flight that comes back to its start.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <optional>

#include "superdyna/eval/evaluate.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/io/trajectory_io.h"
#include "superdyna/system/system.h"
#include "support/generated_sequence.h"
#include "support/test_support.h"

namespace superdyna::system {
namespace {

namespace fs = std::filesystem;

/// A robot base driving 1.3 turns of a circle of 1.5 m radius in 10 s, its camera looking
/// outwards at the room's walls: after one turn (7.7 s) it sees the start again, through map
/// points it made anew (the first ones left its local map long before).
Trajectory circleFlight() {
  Trajectory poses;
  const double turn_s = 7.7;
  for (int i = 0; i <= 1200; ++i) {
    const double t = 0.01 * i;
    const double theta = 2.0 * M_PI * t / turn_s;
    const SE3d T(Eigen::Quaterniond(Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ())),
                 Eigen::Vector3d(1.5 * std::cos(theta), 1.5 * std::sin(theta), 0.0));
    poses.push_back({secondsToNs(100.0 + t), T});
  }
  return poses;
}

const fs::path& circleSequence() {
  static const test::ScratchDir dir("loop_closing_test_motion");
  static const fs::path motion = [] {
    const fs::path file = dir / "circle.txt";
    io::writeTrajectory(file, circleFlight(), io::TrajectoryFormat::kTum);
    return file;
  }();
  sim::SimulationOptions options =
      test::flightOptions(10.0, sim::SceneType::kIndoor, sim::DynamicLevel::kNone, 12);
  options.motion.trajectory_file = motion;
  options.motion.convention = sim::MotionConvention::kForwardX;
  options.landmark_count = 0;
  return test::generatedSequence("loop_closing_test_circle", options);
}

struct LoopRun {
  double ate_m = 0.0;
  double end_drift_m = 0.0;  ///< Position error of the last pose relative to the first.
  LoopSummary loops;
  Trajectory ground_truth;
};

/// The ground-truth pose nearest to t_ns.
SE3d truthAt(const Trajectory& gt, TimeNs t_ns) {
  const StampedPose* best = &gt.front();
  for (const StampedPose& p : gt)
    if (std::llabs(p.t_ns - t_ns) < std::llabs(best->t_ns - t_ns)) best = &p;
  return best->T_w_x;
}

/// How far the last estimated pose is from the truth when both are seen from the first pose: the
/// drift a loop back to the start removes.
double endDrift(const Trajectory& gt, const Trajectory& estimate) {
  const StampedPose& first = estimate.front();
  const StampedPose& last = estimate.back();
  const SE3d truth = truthAt(gt, first.t_ns).inverse() * truthAt(gt, last.t_ns);
  return ((first.T_w_x.inverse() * last.T_w_x).t - truth.t).norm();
}

LoopRun runCircle(SensorMode mode, bool loop_closing, bool deterministic = true) {
  io::DatasetSourceOptions source_options;
  source_options.inertial = usesImu(mode);
  const auto source = io::openDataset(io::DatasetKind::kEuroc, circleSequence(), source_options);
  SystemOptions options;
  options.mode = mode;
  options.deterministic = deterministic;
  options.loop.enabled = loop_closing;
  options.loop.min_time_gap_s = 4.0;  // the revisit comes after 7.7 s
  // Settle the inertial map early enough for the short flight.
  options.mapping.refine_first_s = 2.0;
  options.mapping.refine_second_s = 4.0;
  System slam(options, source->camera0(), source->camera1(), source->imu());
  slam.run(*source);
  eval::EvaluationOptions evaluation;
  evaluation.rpe.unit = eval::DeltaUnit::kFrames;
  LoopRun run;
  run.ate_m = eval::evaluate(source->groundTruth(), slam.trajectory(), evaluation).ate_trans.rmse;
  run.loops = slam.loopSummary();
  run.ground_truth = source->groundTruth();
  run.end_drift_m = endDrift(run.ground_truth, slam.trajectory());
  return run;
}

void expectTrueLoops(const LoopRun& run) {
  for (const loop::LoopClosure& l : run.loops.loops) {
    const SE3d truth =
        truthAt(run.ground_truth, l.match_t_ns).inverse() * truthAt(run.ground_truth, l.query_t_ns);
    const SE3d error = truth.inverse() * l.T_match_query;
    EXPECT_LT(error.t.norm(), 0.05) << "loop " << l.query << " -> " << l.match;
    EXPECT_LT(rotationAngle(error.rotation()), 0.02);
    EXPECT_GE(l.inliers, 60);
  }
}

TEST(LoopClosing, StereoClosesTheCircleAndLowersTheAte) {
  const LoopRun off = runCircle(SensorMode::kStereo, false);
  const LoopRun on = runCircle(SensorMode::kStereo, true);
  EXPECT_TRUE(off.loops.loops.empty());
  ASSERT_GE(on.loops.loops.size(), 1u);
  expectTrueLoops(on);
  // Measured: ATE 6.9 mm without, 5.2 mm with the loop; the last pose seen from the first is off
  // by 20.5 mm without, 8.5 mm with it.
  EXPECT_LT(on.ate_m, 0.8 * off.ate_m);
  EXPECT_LT(on.end_drift_m, 0.5 * off.end_drift_m);
  std::cout << "stereo: ATE " << off.ate_m << " m without loop closing, " << on.ate_m << " m with "
            << on.loops.loops.size() << " loops; end drift " << off.end_drift_m << " m without, "
            << on.end_drift_m << " m with\n";
}

TEST(LoopClosing, StereoClosesTheCircleFromItsOwnThreadInTheConcurrentPipeline) {
  // Detection and verification run in the loop thread, the correction where local mapping runs
  // (at the next keyframe, or at the end of the run). scripts/tsan.sh runs this test too.
  const LoopRun off = runCircle(SensorMode::kStereo, false, false);
  const LoopRun on = runCircle(SensorMode::kStereo, true, false);
  ASSERT_GE(on.loops.loops.size(), 1u);
  expectTrueLoops(on);
  EXPECT_GT(on.loops.keyframes, 10u);
  // Measured in 19 pairs of concurrent runs, two or three test processes at a time: the last pose
  // seen from the first is off by 17.8-20.8 mm without, 8.6-10.6 mm with the loop, and once, three
  // processes on two cores, 13.3 mm with it. The ATE of the whole circle moves less (6.8-7.0 mm
  // without, 5.5-6.6 mm with; a CI run under load saw 7.0 against 6.6 mm), so the drift the loop
  // removes is what is asserted, and of the ATE only that the loop does not make it worse.
  EXPECT_LT(on.end_drift_m, 0.8 * off.end_drift_m);
  EXPECT_LT(on.ate_m, 1.05 * off.ate_m);
  std::cout << "stereo, concurrent: ATE " << off.ate_m << " m without loop closing, " << on.ate_m
            << " m with " << on.loops.loops.size() << " loops (" << on.loops.skipped
            << " keyframes skipped by the busy loop thread); end drift " << off.end_drift_m
            << " m without, " << on.end_drift_m << " m with\n";
}

TEST(LoopClosing, StereoInertialAcceptsNoFalseLoopAndDoesNotHurt) {
  // On this flight the inertial map settles late (4 s) and its two consistent candidates fail the
  // RANSAC: no loop, and then the run must equal the one without loop closing.
  const LoopRun off = runCircle(SensorMode::kStereoInertial, false);
  const LoopRun on = runCircle(SensorMode::kStereoInertial, true);
  expectTrueLoops(on);
  EXPECT_GT(on.loops.keyframes, 10u);  // it did query the database
  EXPECT_LE(on.ate_m, off.ate_m * 1.0001);
  std::cout << "stereo-inertial: ATE " << off.ate_m << " m without loop closing, " << on.ate_m
            << " m with " << on.loops.loops.size() << " loops\n";
}

struct KidnapRun {
  int relocalizations = 0;
  int resets = 0;
  std::size_t lost_after_jump = 0;
  std::size_t tracked_after_jump = 0;
  double max_error_after_jump_m = 0.0;  ///< Tracked frames, against the truth at the same times.
};

/// Stereo over the circle with the frames from 4.0 to 8.3 s left out: at 8.3 s the rig is back
/// where it was at 0.6 s, half a circle from where the constant-velocity model expects it and
/// looking the other way, so neither the prediction nor the reference keyframe can place it.
KidnapRun runKidnapped(bool loop_closing, bool deterministic = true) {
  const auto source = io::openDataset(io::DatasetKind::kEuroc, circleSequence(), {});
  SystemOptions options;
  options.mode = SensorMode::kStereo;
  options.deterministic = deterministic;
  options.loop.enabled = loop_closing;
  options.loop.min_time_gap_s = 4.0;
  System slam(options, source->camera0(), source->camera1(), source->imu());
  const Trajectory truth = source->groundTruth();
  std::optional<TimeNs> t_first;
  KidnapRun run;
  SE3d T_truth_est;  // the map's frame in the truth's, from the first frame
  while (auto frame = source->next()) {
    if (!t_first) t_first = frame->t_ns;
    const double t_s = nsToSeconds(frame->t_ns - *t_first);
    if (t_s >= 4.0 && t_s < 8.3) continue;
    const tracking::TrackingResult result = slam.process(*frame);
    if (frame->t_ns == *t_first) T_truth_est = truthAt(truth, frame->t_ns) * result.T_w_b.inverse();
    if (t_s < 8.3) continue;
    if (result.state != tracking::TrackingState::kTracking) {
      ++run.lost_after_jump;
      continue;
    }
    ++run.tracked_after_jump;
    const double error = ((T_truth_est * result.T_w_b).t - truthAt(truth, frame->t_ns).t).norm();
    run.max_error_after_jump_m = std::max(run.max_error_after_jump_m, error);
  }
  run.relocalizations = slam.relocalizations();
  run.resets = slam.resets();
  slam.finish();
  std::cout << "kidnapped stereo, " << (deterministic ? "deterministic" : "concurrent")
            << ", loop closing " << (loop_closing ? "on" : "off") << ": " << run.relocalizations
            << " relocalisations, " << run.resets << " resets, " << run.tracked_after_jump
            << " frames tracked and " << run.lost_after_jump
            << " lost after the jump, largest position error " << run.max_error_after_jump_m
            << " m\n";
  return run;
}

TEST(Relocalisation, PlaceRecognitionFindsAKidnappedRigInItsMap) {
  const KidnapRun with_places = runKidnapped(true);
  EXPECT_EQ(with_places.relocalizations, 1);
  EXPECT_EQ(with_places.resets, 0);
  EXPECT_EQ(with_places.lost_after_jump, 0u);  // the first frame after the jump is located
  EXPECT_GT(with_places.tracked_after_jump, 30u);
  EXPECT_LT(with_places.max_error_after_jump_m, 0.05);
  // Without place recognition the candidates are the keyframes near the prediction, which look
  // the other way: measured, the frames stay lost until the constant-velocity model has carried
  // the prediction on along the circle to keyframes that see the place (10 frames).
  const KidnapRun near_only = runKidnapped(false);
  EXPECT_GE(near_only.lost_after_jump, 5u);
  EXPECT_EQ(near_only.resets, 0);
}

TEST(Relocalisation, PlaceRecognitionWorksWhileLoopClosingRunsInTheMappingThread) {
  // The tracker queries the loop closer's database from its own thread (LoopCloser::recognize)
  // while the loop thread adds to it; scripts/tsan.sh runs this test under ThreadSanitizer.
  const KidnapRun run = runKidnapped(true, false);
  EXPECT_GE(run.relocalizations, 1);
  EXPECT_EQ(run.resets, 0);
  EXPECT_LE(run.lost_after_jump, 2u);
  EXPECT_LT(run.max_error_after_jump_m, 0.05);
}

}  // namespace
}  // namespace superdyna::system

// Loop closing in the whole system: a short indoor flight that comes back to its start.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <iostream>

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
  LoopSummary loops;
  Trajectory ground_truth;
};

LoopRun runCircle(SensorMode mode, bool loop_closing) {
  io::DatasetSourceOptions source_options;
  source_options.inertial = usesImu(mode);
  const auto source = io::openDataset(io::DatasetKind::kEuroc, circleSequence(), source_options);
  SystemOptions options;
  options.mode = mode;
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
  return run;
}

/// The ground-truth pose nearest to t_ns.
SE3d truthAt(const Trajectory& gt, TimeNs t_ns) {
  const StampedPose* best = &gt.front();
  for (const StampedPose& p : gt)
    if (std::llabs(p.t_ns - t_ns) < std::llabs(best->t_ns - t_ns)) best = &p;
  return best->T_w_x;
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
  // Measured: 14.7 mm without, 9.7 mm with the loop.
  EXPECT_LT(on.ate_m, 0.8 * off.ate_m);
  std::cout << "stereo: ATE " << off.ate_m << " m without loop closing, " << on.ate_m << " m with "
            << on.loops.loops.size() << " loops\n";
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

}  // namespace
}  // namespace superdyna::system

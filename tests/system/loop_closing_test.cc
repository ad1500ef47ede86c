// Loop closing in the whole system: a short indoor flight that comes back to its start.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <memory>
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
/// points it made anew (the first ones left its local map long before). `wobble` varies the speed
/// along the circle and moves the rig up and down, so that a monocular IMU sees its scale: on the
/// plain circle the acceleration is constant in the body frame and mono-inertial's scale comes out
/// 0.81.
Trajectory circleFlight(bool wobble, double duration_s) {
  Trajectory poses;
  const double turn_s = 7.7;
  for (int i = 0; i <= static_cast<int>(std::lround(duration_s * 100.0)) + 200; ++i) {
    const double t = 0.01 * i;
    double theta = 2.0 * M_PI * t / turn_s;
    double z = 0.0;
    if (wobble) {
      theta += 0.25 * std::sin(2.0 * M_PI * t / 2.3);
      z = 0.25 * std::sin(2.0 * M_PI * t / 3.1);
    }
    const SE3d T(Eigen::Quaterniond(Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ())),
                 Eigen::Vector3d(1.5 * std::cos(theta), 1.5 * std::sin(theta), z));
    poses.push_back({secondsToNs(100.0 + t), T});
  }
  return poses;
}

/// texture_variety: sim::WorldOptions::texture_variety (1: every wall, floor tile and ceiling
/// alike).
fs::path simulatedCircle(const std::string& name, bool wobble, double duration_s,
                         int texture_variety = 0) {
  const test::ScratchDir dir(name + "_motion");
  const fs::path motion = dir / "circle.txt";
  io::writeTrajectory(motion, circleFlight(wobble, duration_s), io::TrajectoryFormat::kTum);
  sim::SimulationOptions options =
      test::flightOptions(duration_s, sim::SceneType::kIndoor, sim::DynamicLevel::kNone, 12);
  options.motion.trajectory_file = motion;
  options.motion.convention = sim::MotionConvention::kForwardX;
  options.landmark_count = 0;
  options.world.texture_variety = texture_variety;
  return test::generatedSequence(name, options);
}

const fs::path& circleSequence() {
  static const fs::path sequence = simulatedCircle("loop_closing_test_circle", false, 10.0);
  return sequence;
}

const fs::path& wobblingCircleSequence() {
  static const fs::path sequence = simulatedCircle("loop_closing_test_wobble", true, 13.0);
  return sequence;
}

/// The wobbling circle in a room whose walls, floor tiles and clutter each share one texture: the
/// camera, looking outwards, sees the same wall wherever it turns.
const fs::path& aliasedCircleSequence() {
  static const fs::path sequence = simulatedCircle("loop_closing_test_aliased", true, 13.0, 1);
  return sequence;
}

struct LoopRun {
  double ate_m = 0.0;
  double end_drift_m = 0.0;  ///< Position error of the last pose relative to the first.
  std::size_t lost_frames = 0;
  int resets = 0;
  LoopSummary loops;
  Trajectory ground_truth;
  SE3d T_b_c;  ///< The left camera's.
};

/// The ground-truth pose nearest to t_ns.
SE3d truthAt(const Trajectory& gt, TimeNs t_ns) {
  const StampedPose* best = &gt.front();
  for (const StampedPose& p : gt)
    if (std::llabs(p.t_ns - t_ns) < std::llabs(best->t_ns - t_ns)) best = &p;
  return best->T_w_x;
}

/// How far the last estimated pose of X is from the truth when both are seen from the first pose
/// (the estimate's lengths times `scale`): the drift a loop back to the start removes. X is the
/// body moved by T_b_x: a monocular map places its bodies by the metric camera-body lever arm in
/// the map's own unit, so its drift is measured between cameras.
double endDrift(const Trajectory& gt, const Trajectory& estimate, double scale, const SE3d& T_b_x) {
  const StampedPose& first = estimate.front();
  const StampedPose& last = estimate.back();
  const SE3d truth = (truthAt(gt, first.t_ns) * T_b_x).inverse() * (truthAt(gt, last.t_ns) * T_b_x);
  const SE3d estimated = (first.T_w_x * T_b_x).inverse() * (last.T_w_x * T_b_x);
  return (scale * estimated.t - truth.t).norm();
}

/// The options of every run here: the loop's time gap and an inertial map that settles early
/// enough for the short flights.
SystemOptions circleOptions(SystemOptions options, SensorMode mode, bool loop_closing,
                            bool deterministic) {
  options.mode = mode;
  options.deterministic = deterministic;
  options.loop.enabled = loop_closing;
  options.loop.min_time_gap_s = 4.0;  // the revisit comes after 7.7 s
  options.mapping.refine_first_s = 2.0;
  options.mapping.refine_second_s = 4.0;
  return options;
}

/// The sequence with the sensors `mode` uses.
std::unique_ptr<io::DatasetSource> openSequence(const fs::path& sequence, SensorMode mode) {
  io::DatasetSourceOptions source_options;
  source_options.inertial = usesImu(mode);
  source_options.stereo = !isMonocular(mode);
  return io::openDataset(io::DatasetKind::kEuroc, sequence, source_options);
}

/// RPE over frames; a monocular map has its own unit: it is compared after a similarity
/// alignment.
eval::EvaluationOptions evaluationOptions(SensorMode mode) {
  eval::EvaluationOptions evaluation;
  evaluation.rpe.unit = eval::DeltaUnit::kFrames;
  if (mode == SensorMode::kMono) evaluation.align = eval::AlignmentMode::kSim3;
  return evaluation;
}

LoopRun runOn(const fs::path& sequence, const SystemOptions& options) {
  const auto source = openSequence(sequence, options.mode);
  System slam(options, source->camera0(), source->camera1(), source->imu());
  slam.run(*source);
  const eval::EvaluationResult result =
      eval::evaluate(source->groundTruth(), slam.trajectory(), evaluationOptions(options.mode));
  LoopRun run;
  run.ate_m = result.ate_trans.rmse;
  run.loops = slam.loopSummary();
  run.lost_frames = slam.lostFrames();
  run.resets = slam.resets();
  run.ground_truth = source->groundTruth();
  run.T_b_c = source->camera0().T_b_c;
  run.end_drift_m = endDrift(run.ground_truth, slam.trajectory(), result.alignment.s,
                             options.mode == SensorMode::kMono ? run.T_b_c : SE3d());
  return run;
}

LoopRun runCircle(SensorMode mode, bool loop_closing, bool deterministic = true) {
  return runOn(circleSequence(), circleOptions({}, mode, loop_closing, deterministic));
}

/// Each loop's (or merge's) relative pose of its query and match keyframes (after the
/// correction) is the true one, within 5 cm and 0.02 rad, from at least 60 inliers.
void expectTrueClosures(const std::vector<loop::LoopClosure>& closures, const Trajectory& gt,
                        const SE3d& T_b_c) {
  for (const loop::LoopClosure& l : closures) {
    const SE3d truth = truthAt(gt, l.match_t_ns).inverse() * truthAt(gt, l.query_t_ns);
    const SE3d error = loop::loopError(l, truth, T_b_c);
    EXPECT_LT(error.t.norm(), 0.05)
        << (l.merge ? "merge " : "loop ") << l.query << " -> " << l.match;
    EXPECT_LT(rotationAngle(error.rotation()), 0.02);
    EXPECT_GE(l.inliers, 60);
  }
}

void expectTrueLoops(const LoopRun& run) {
  expectTrueClosures(run.loops.loops, run.ground_truth, run.T_b_c);
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
  // On this flight the inertial map settles late (4 s). Whatever loop it accepts must be true and
  // must not make the run worse (measured: one loop, ATE 11.1 mm without, 5.6 mm with; earlier
  // versions found none, and then the run equalled the one without loop closing).
  const LoopRun off = runCircle(SensorMode::kStereoInertial, false);
  const LoopRun on = runCircle(SensorMode::kStereoInertial, true);
  expectTrueLoops(on);
  EXPECT_GT(on.loops.keyframes, 10u);  // it did query the database
  EXPECT_LE(on.ate_m, off.ate_m * 1.0001);
  std::cout << "stereo-inertial: ATE " << off.ate_m << " m without loop closing, " << on.ate_m
            << " m with " << on.loops.loops.size() << " loops\n";
}

// A mono-inertial map has the IMU's scale once its inertial stages have run; from then on its
// keyframes go to loop closing, and its loops are SE(3) with a 4-DoF correction as
// stereo-inertial's.
TEST(LoopClosing, MonoInertialClosesTheWobblingCircleOnceItsScaleIsSettled) {
  const SystemOptions shipped =
      loadSystemOptions(fs::path(SUPERDYNA_SOURCE_DIR) / "configs" / "euroc_mono_inertial.yaml");
  const LoopRun off = runOn(wobblingCircleSequence(),
                            circleOptions(shipped, SensorMode::kMonoInertial, false, true));
  const LoopRun on = runOn(wobblingCircleSequence(),
                           circleOptions(shipped, SensorMode::kMonoInertial, true, true));
  EXPECT_TRUE(off.loops.loops.empty());
  ASSERT_GE(on.loops.loops.size(), 1u);
  expectTrueLoops(on);
  // Measured (the shipped config: a global BA after the loop): ATE 17.2 mm without, 7.3 mm with
  // the loop (9.9 mm without the global BA); the last pose seen from the first is off by 40 mm
  // without, 3.5 mm with it (22 mm without the global BA).
  EXPECT_LT(on.ate_m, 0.8 * off.ate_m);
  EXPECT_LT(on.end_drift_m, 0.7 * off.end_drift_m);
  std::cout << "mono-inertial: ATE " << off.ate_m << " m without loop closing, " << on.ate_m
            << " m with " << on.loops.loops.size() << " loops; end drift " << off.end_drift_m
            << " m without, " << on.end_drift_m << " m with\n";
}

// Concurrent mono-inertial tracking waits for each keyframe's mapping job, before the IMU is
// initialised too: the wobbling circle turns fast, and frames tracked while the mapper has not yet
// triangulated the new keyframe's points ran out of map points (measured without that wait, 8
// runs outside the tests: 4 lost track about 0.6 s after the keyframe at 2 s and reset the map,
// ATE 13-25 m). Three runs, so that a return of that failure is all but certain to show. The
// global BA after the loop runs in a thread of its own that tracking does not wait for, and lands.
TEST(LoopClosing, MonoInertialConcurrentTracksTheWobblingCircleAndLandsTheGlobalBa) {
  const SystemOptions shipped =
      loadSystemOptions(fs::path(SUPERDYNA_SOURCE_DIR) / "configs" / "euroc_mono_inertial.yaml");
  for (int run = 0; run < 3; ++run) {
    const LoopRun on = runOn(wobblingCircleSequence(),
                             circleOptions(shipped, SensorMode::kMonoInertial, true, false));
    EXPECT_EQ(on.lost_frames, 0u) << "run " << run;
    EXPECT_EQ(on.resets, 0) << "run " << run;
    ASSERT_GE(on.loops.loops.size(), 1u) << "run " << run;
    expectTrueLoops(on);
    EXPECT_GE(on.loops.global_bas, 1) << "run " << run;
    // Measured: ATE 7.2 mm in each of 8 runs outside the tests (the global BA inline); the end
    // drift as in the deterministic test above, 3.5 mm with the global BA, 40 mm without a loop.
    EXPECT_LT(on.ate_m, 0.03) << "run " << run;
    EXPECT_LT(on.end_drift_m, 0.02) << "run " << run;
    std::cout << "mono-inertial, concurrent, run " << run << ": ATE " << on.ate_m << " m, "
              << on.lost_frames << " frames lost, " << on.loops.loops.size() << " loops, "
              << on.loops.global_bas << " global BAs landed (" << on.loops.global_bas_dropped
              << " dropped), end drift " << on.end_drift_m << " m\n";
  }
}

// A monocular map's scale drifts: its loops are similarities (Sim(3) RANSAC, 7-DoF pose graph),
// and the correction rescales the keyframes and points on the query's side.
TEST(LoopClosing, MonoClosesTheWobblingCircleWithASimilarity) {
  const SystemOptions shipped =
      loadSystemOptions(fs::path(SUPERDYNA_SOURCE_DIR) / "configs" / "euroc_mono.yaml");
  const LoopRun off =
      runOn(wobblingCircleSequence(), circleOptions(shipped, SensorMode::kMono, false, true));
  const LoopRun on =
      runOn(wobblingCircleSequence(), circleOptions(shipped, SensorMode::kMono, true, true));
  EXPECT_TRUE(off.loops.loops.empty());
  ASSERT_GE(on.loops.loops.size(), 1u);
  expectTrueLoops(on);
  for (const loop::LoopClosure& l : on.loops.loops)
    EXPECT_NE(l.scale, 1.0);  // a similarity, its scale estimated
  // Measured (Sim(3)-aligned): ATE 34.2 mm without, 14.5 mm with two loops. (The drift of the
  // last pose is not asserted here: seen from the first at one scale for the whole run, it mixes
  // in the scale the map has at the end.)
  EXPECT_LT(on.ate_m, 0.6 * off.ate_m);
  std::cout << "mono: ATE " << off.ate_m << " m without loop closing, " << on.ate_m << " m with "
            << on.loops.loops.size() << " loops (scale " << on.loops.loops.front().scale << ")\n";
}

/// Loops of `run` farther than 0.5 m or 5 degrees from the true relative pose (run's "false").
int falseLoops(const LoopRun& run) {
  int wrong = 0;
  for (const loop::LoopClosure& l : run.loops.loops) {
    const SE3d truth =
        truthAt(run.ground_truth, l.match_t_ns).inverse() * truthAt(run.ground_truth, l.query_t_ns);
    const SE3d error = loop::loopError(l, truth, run.T_b_c);
    wrong += error.t.norm() > 0.5 || rotationAngle(error.rotation()) > 5.0 * M_PI / 180.0;
  }
  return wrong;
}

// Perceptual aliasing: in a room of repeated textures another wall looks like the one seen
// before, and its points fit a rigid (or similar) transform as well as the true place's do. Such
// a "loop" turns the map by tens of degrees, far beyond what the odometry drifts between the two
// keyframes: the drift bound rejects it.
TEST(LoopClosing, MonoAcceptsNoFalseLoopInARoomOfRepeatedTextures) {
  const SystemOptions shipped =
      loadSystemOptions(fs::path(SUPERDYNA_SOURCE_DIR) / "configs" / "euroc_mono.yaml");
  SystemOptions unbounded = circleOptions(shipped, SensorMode::kMono, true, true);
  unbounded.loop.max_correction_deg = 180.0;
  unbounded.loop.max_correction_path_share = 1e6;
  const LoopRun aliased = runOn(aliasedCircleSequence(), unbounded);
  const LoopRun bounded =
      runOn(aliasedCircleSequence(), circleOptions(shipped, SensorMode::kMono, true, true));
  const auto beyond_drift = static_cast<int>(loop::Rejection::kBeyondDrift);
  EXPECT_GE(falseLoops(aliased), 1);  // the aliasing is real
  EXPECT_EQ(falseLoops(bounded), 0);
  EXPECT_GE(bounded.loops.rejected[beyond_drift], 1u);
  std::cout << "mono, repeated textures: " << aliased.loops.loops.size() << " loops, "
            << falseLoops(aliased) << " false without the drift bound (ATE " << aliased.ate_m
            << " m); " << bounded.loops.loops.size() << " loops, " << falseLoops(bounded)
            << " false, " << bounded.loops.rejected[beyond_drift]
            << " candidates beyond the drift with it (ATE " << bounded.ate_m << " m)\n";
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

struct MergeRun {
  double ate_m = 0.0;
  double seen_ate_m = 0.0;  ///< Without the black frames.
  int resets = 0;
  std::size_t lost = 0;
  std::size_t poses = 0;
  LoopSummary loops;
  std::size_t keyframes = 0;  ///< In the map at the end.
  Trajectory ground_truth;
  SE3d T_b_c;  ///< The left camera's.
};

void expectTrueMerges(const MergeRun& run) {
  expectTrueClosures(run.loops.merges, run.ground_truth, run.T_b_c);
}

using test::Blackout;

/// `options` over `sequence` with the blackout, without relocalisation (tracker.relocalization_s
/// 0): the first frame tracking fails at, or the first after the IMU bridge, leaves the map, and a
/// new one starts as soon as the images allow.
MergeRun runBlackout(const fs::path& sequence, SystemOptions options, const Blackout& blackout) {
  const auto source = openSequence(sequence, options.mode);
  options.tracker.relocalization_s = 0.0;
  System slam(options, source->camera0(), source->camera1(), source->imu());
  std::optional<TimeNs> t_first;
  while (auto frame = source->next()) {
    if (!t_first) t_first = frame->t_ns;
    blackout.apply(*frame, nsToSeconds(frame->t_ns - *t_first));
    slam.process(*frame);
  }
  slam.finish();
  const eval::EvaluationOptions evaluation = evaluationOptions(options.mode);
  const Trajectory trajectory = slam.trajectory();
  MergeRun run;
  run.ate_m = eval::evaluate(source->groundTruth(), trajectory, evaluation).ate_trans.rmse;
  Trajectory seen;  // the black frames' poses are constant-velocity predictions
  for (const StampedPose& p : trajectory)
    if (!blackout.covers(nsToSeconds(p.t_ns - *t_first))) seen.push_back(p);
  run.seen_ate_m = eval::evaluate(source->groundTruth(), seen, evaluation).ate_trans.rmse;
  run.resets = slam.resets();
  run.lost = slam.lostFrames();
  run.poses = trajectory.size();
  run.loops = slam.loopSummary();
  run.keyframes = slam.numKeyFrames();
  run.ground_truth = source->groundTruth();
  run.T_b_c = source->camera0().T_b_c;
  std::cout << toString(options.mode) << ", black " << blackout.t0_s << "-" << blackout.t1_s
            << " s, " << (options.deterministic ? "deterministic" : "concurrent")
            << ", loop closing " << (options.loop.enabled ? "on" : "off") << ": ATE " << run.ate_m
            << " m (" << run.seen_ate_m << " m without the black frames), " << run.resets
            << " new maps, " << run.loops.merges.size() << " merges, " << run.loops.atlas_maps
            << " maps left unmerged, " << run.keyframes << " keyframes in the map at the end\n";
  for (const loop::LoopClosure& m : run.loops.merges) {
    std::cout << "  merge: " << nsToSeconds(m.query_t_ns - *t_first) << " s -> "
              << nsToSeconds(m.match_t_ns - *t_first) << " s, " << m.inliers << " inliers\n";
  }
  return run;
}

/// `options` over `sequence` with the blackout, with loop closing (so the atlas) and without:
/// both start one new map after it; with the atlas it is merged once, truly.
struct MergeComparison {
  MergeRun merged;
  MergeRun apart;
};
MergeComparison compareMerging(const fs::path& sequence, SystemOptions options,
                               const Blackout& blackout) {
  MergeComparison runs;
  options.loop.enabled = true;
  runs.merged = runBlackout(sequence, options, blackout);
  options.loop.enabled = false;
  runs.apart = runBlackout(sequence, options, blackout);
  EXPECT_EQ(runs.merged.resets, 1);
  EXPECT_EQ(runs.apart.resets, 1);
  EXPECT_EQ(runs.merged.poses, runs.apart.poses);
  EXPECT_EQ(runs.merged.loops.merges.size(), 1u);
  EXPECT_EQ(runs.merged.loops.atlas_maps, 0u);
  expectTrueMerges(runs.merged);
  return runs;
}

/// The map left at the blackout goes to the atlas; the new map recognises its first place when the
/// rig comes round and absorbs it, moved into its frame: one map, one frame at the end. Loop
/// closing off (no atlas) leaves the two parts of the trajectory in unrelated frames.
TEST(MapMerging, StereoMergesTheMapLeftAtABlackoutWhenItComesRound) {
  const auto [merged, apart] = compareMerging(
      circleSequence(), circleOptions({}, SensorMode::kStereo, true, true), {2.0, 3.0});
  ASSERT_EQ(merged.loops.merges.size(), 1u);
  const loop::LoopClosure& merge = merged.loops.merges.front();
  EXPECT_LT(nsToSeconds(merge.match_t_ns - merge.query_t_ns), -5.0);  // a place of the first map
  // Measured: 5.8 mm without the black frames (36.8 mm with them) against 82.2 mm (79.7 mm) with
  // the maps apart; the circle without blackout: 5.2 mm.
  EXPECT_LT(merged.seen_ate_m, 0.01);
  EXPECT_LT(merged.seen_ate_m, 0.2 * apart.seen_ate_m);
  EXPECT_LT(merged.ate_m, 0.5 * apart.ate_m);
}

/// The shipped configuration of `mode` with the circle runs' settings.
SystemOptions shippedCircleOptions(SensorMode mode, const std::string& config,
                                   bool deterministic = true) {
  return circleOptions(loadSystemOptions(fs::path(SUPERDYNA_SOURCE_DIR) / "configs" / config), mode,
                       true, deterministic);
}

/// A monocular map after the blackout has a scale of its own: the merge is a similarity, and the
/// merged map has the active map's unit. Measured: 17.5 mm (Sim(3)-aligned, without the black
/// frames) against 712 mm with the two maps apart.
TEST(MapMerging, MonoMergesTheMapLeftAtABlackoutWithASimilarity) {
  const auto [merged, apart] =
      compareMerging(wobblingCircleSequence(),
                     shippedCircleOptions(SensorMode::kMono, "euroc_mono.yaml"), {5.0, 6.0});
  ASSERT_EQ(merged.loops.merges.size(), 1u);
  EXPECT_NE(merged.loops.merges.front().scale, 1.0);
  EXPECT_LT(merged.seen_ate_m, 0.03);
  EXPECT_LT(merged.seen_ate_m, 0.1 * apart.seen_ate_m);
}

/// Inertial maps are merged only once both have run their inertial stages (the map left must no
/// longer move as a whole): a blackout at 5 s leaves a settled map (its last stage ran at 4 s),
/// merged by yaw and position when the new map, settled in turn, comes round (measured: 7.6 mm
/// without the black frames against 36.8 mm apart); at 4 s the map left is dropped instead.
TEST(MapMerging, StereoInertialMergesSettledMapsOnly) {
  const SystemOptions options =
      shippedCircleOptions(SensorMode::kStereoInertial, "euroc_stereo_inertial.yaml");
  const auto [merged, apart] = compareMerging(wobblingCircleSequence(), options, {5.0, 6.0});
  ASSERT_EQ(merged.loops.merges.size(), 1u);
  EXPECT_EQ(merged.loops.merges.front().scale, 1.0);
  EXPECT_LT(merged.seen_ate_m, 0.015);
  EXPECT_LT(merged.seen_ate_m, 0.5 * apart.seen_ate_m);
  const MergeRun unsettled = runBlackout(wobblingCircleSequence(), options, {4.0, 5.0});
  EXPECT_EQ(unsettled.resets, 1);
  EXPECT_TRUE(unsettled.loops.merges.empty());
  EXPECT_EQ(unsettled.loops.atlas_maps, 0u);
}

/// Mono-inertial: the new map gets its metric scale from its own inertial initialisation, so the
/// merge is rigid (yaw and position). Measured: 17.8 mm without the black frames against 4.08 m
/// apart.
TEST(MapMerging, MonoInertialMergesTheMapLeftAtABlackout) {
  const auto [merged, apart] = compareMerging(
      wobblingCircleSequence(),
      shippedCircleOptions(SensorMode::kMonoInertial, "euroc_mono_inertial.yaml"), {5.0, 6.0});
  EXPECT_LT(merged.seen_ate_m, 0.03);
  EXPECT_LT(merged.seen_ate_m, 0.1 * apart.seen_ate_m);
}

/// The concurrent pipeline: the merge is found in the loop thread and applied in the mapping
/// thread while tracking goes on (scripts/tsan.sh runs this test under ThreadSanitizer).
TEST(MapMerging, StereoMergesInTheConcurrentPipeline) {
  const MergeRun merged = runBlackout(
      circleSequence(), circleOptions({}, SensorMode::kStereo, true, false), {2.0, 3.0});
  EXPECT_EQ(merged.resets, 1);
  ASSERT_EQ(merged.loops.merges.size(), 1u);
  expectTrueMerges(merged);
  EXPECT_LT(merged.seen_ate_m, 0.015);
}

}  // namespace
}  // namespace superdyna::system

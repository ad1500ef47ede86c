#include "superdyna/tracking/tracker.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <cstdio>
#include <deque>
#include <functional>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <utility>
#include <vector>

#include "superdyna/eval/statistics.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/sim/sequence_generator.h"
#include "superdyna/tracking/front_end.h"
#include "support/generated_sequence.h"
#include "support/test_support.h"

namespace superdyna::tracking {
namespace {

sensors::CameraCalibration calibrationOf(const sim::RigOptions& rig, const SE3d& T_b_c) {
  sensors::CameraCalibration c;
  c.name = "cam";
  c.T_b_c = T_b_c;
  c.width = rig.width;
  c.height = rig.height;
  c.rate_hz = rig.camera_rate_hz;
  c.fx = rig.fx;
  c.fy = rig.fy;
  c.cx = rig.cx;
  c.cy = rig.cy;
  return c;
}

Tracker makeTracker(const TrackerOptions& options = {}) {
  const sim::RigOptions rig;
  return Tracker(options, PyramidInfo{}, mapping::LocalMapperOptions{},
                 calibrationOf(rig, rig.T_b_c0()), calibrationOf(rig, rig.T_b_c1()), std::nullopt);
}

FrontEnd makeFrontEnd(const FrontEndOptions& options = {}) {
  const sim::RigOptions rig;
  return FrontEnd(options, calibrationOf(rig, rig.T_b_c0()), calibrationOf(rig, rig.T_b_c1()));
}

/// A mapping "thread" that runs a job only when more than `lag` jobs wait (the oldest first), and
/// all of them when the tracker waits for it (waitIdle). lag 0: a mapper that runs each job at once
/// (always idle); kNeverOnItsOwn: one that never runs on its own, so from the tracker's point of
/// view local mapping is busy from each keyframe until it waits; in between, one that stays `lag`
/// jobs behind (two jobs per keyframe: registering it, then its local mapping), as a mapper that
/// cannot keep up with keyframes at car speed.
class ManualMappingSink final : public MappingSink {
 public:
  static constexpr std::size_t kNeverOnItsOwn = std::numeric_limits<std::size_t>::max();
  explicit ManualMappingSink(std::size_t lag) : lag_(lag) {}
  void submit(std::function<void()> job) override {
    jobs_.push_back(std::move(job));
    while (jobs_.size() > lag_)
      runOldest();
  }
  void discardPending() override { jobs_.clear(); }
  void waitIdle() override {
    while (!jobs_.empty())
      runOldest();
  }
  bool busy() const override { return !jobs_.empty(); }
  std::size_t pending() const { return jobs_.size(); }

 private:
  void runOldest() {
    std::function<void()> job = std::move(jobs_.front());
    jobs_.pop_front();
    job();
  }
  std::size_t lag_;
  std::deque<std::function<void()>> jobs_;
};

/// A 3 s street flight, generated once for the monocular tests here.
const std::filesystem::path& monoSequence() {
  return test::generatedSequence(
      "tracker_test_street",
      test::flightOptions(3.0, sim::SceneType::kStreet, sim::DynamicLevel::kNone, 7));
}

/// monoSequence() made longer: the mono-inertial tests need keyframes after the inertial
/// initialisation, which succeeds 2.2 s into the map when tracking waits for each keyframe's
/// mapping.
const std::filesystem::path& longMonoSequence() {
  return test::generatedSequence(
      "tracker_test_street_long",
      test::flightOptions(4.5, sim::SceneType::kStreet, sim::DynamicLevel::kNone, 7));
}

/// monoSequence() (`long_flight`: longMonoSequence()) as a monocular source, with its IMU when
/// `inertial`.
std::unique_ptr<io::DatasetSource> openMonoSequence(bool inertial, bool long_flight = false) {
  io::DatasetSourceOptions source_options;
  source_options.stereo = false;
  source_options.inertial = inertial;
  return io::openDataset(io::DatasetKind::kEuroc, long_flight ? longMonoSequence() : monoSequence(),
                         source_options);
}

struct MonoKeyFrame {
  TimeNs t_ns = 0;
  int inliers = 0;
  std::size_t pending_jobs = 0;  ///< Mapping jobs queued after the keyframe's frame.
};

struct MonoRun {
  std::vector<MonoKeyFrame> keyframes;  ///< Inserted while tracking (not the two-view ones).
  int lost = 0;
  int resets = 0;
  std::size_t max_pending_jobs = 0;
};

/// Tracks monoSequence() with a monocular tracker (mapping jobs to `sink`, if any).
MonoRun trackMono(const TrackerOptions& options, ManualMappingSink* sink) {
  const auto source = openMonoSequence(false);
  FrontEnd front_end(FrontEndOptions{}, source->camera0(), std::nullopt);
  mapping::LocalMapperOptions mapping;
  mapping.triangulate = true;
  Tracker tracker(options, PyramidInfo{}, mapping, source->camera0(), std::nullopt, std::nullopt);
  tracker.setMappingSink(sink);
  MonoRun run;
  while (const auto bundle = source->next()) {
    const TrackingResult result = tracker.track(front_end.build(*bundle));
    const std::size_t pending = sink ? sink->pending() : 0;
    run.max_pending_jobs = std::max(run.max_pending_jobs, pending);
    if (result.state == TrackingState::kLost) ++run.lost;
    if (result.keyframe && result.state == TrackingState::kTracking) {
      run.keyframes.push_back({bundle->t_ns, result.inliers, pending});
    }
  }
  run.resets = tracker.resets();
  return run;
}

/// Shortest time between consecutive `times` [s]; infinite for fewer than two.
double minGapSeconds(const std::vector<TimeNs>& times) {
  double gap = std::numeric_limits<double>::infinity();
  for (std::size_t i = 1; i < times.size(); ++i)
    gap = std::min(gap, nsToSeconds(times[i] - times[i - 1]));
  return gap;
}

/// Smallest gap between consecutive tracked keyframes [s].
double minKeyFrameGapSeconds(const MonoRun& run) {
  std::vector<TimeNs> times;
  for (const MonoKeyFrame& kf : run.keyframes)
    times.push_back(kf.t_ns);
  return minGapSeconds(times);
}

TEST(MonoTracker, NeverRunsMoreThanOneKeyFrameAheadOfABusyMapper) {
  TrackerOptions options;
  options.keyframe_tracked_ratio = 0.9;
  options.keyframe_max_interval_s = 0.5;
  options.keyframe_weak_inliers = 0;  // never weak: keyframes only when overdue
  options.mono_wait_for_mapping = false;
  ManualMappingSink busy(ManualMappingSink::kNeverOnItsOwn);
  const MonoRun overdue_only = trackMono(options, &busy);
  EXPECT_EQ(overdue_only.lost, 0);
  EXPECT_EQ(overdue_only.resets, 0);
  ASSERT_GE(overdue_only.keyframes.size(), 3u);
  // Each keyframe leaves exactly its own two jobs (registration, local mapping) queued: the
  // tracker waited for the previous keyframe's jobs before inserting it.
  for (const MonoKeyFrame& kf : overdue_only.keyframes)
    EXPECT_EQ(kf.pending_jobs, 2u);
  EXPECT_EQ(overdue_only.max_pending_jobs, 2u);
  // Refused while the mapper is busy: only the overdue ones, 0.5 s (10 frames) apart.
  EXPECT_GE(minKeyFrameGapSeconds(overdue_only), 0.5 - 1e-6);

  // Weak tracking: the tracker waits for the busy mapper and inserts the keyframe at once.
  options.keyframe_weak_inliers = 100000;  // always weak
  const MonoRun weak = trackMono(options, &busy);
  EXPECT_EQ(weak.lost, 0);
  EXPECT_EQ(weak.max_pending_jobs, 2u);
  EXPECT_GE(weak.keyframes.size(), 2 * overdue_only.keyframes.size());
  EXPECT_LT(minKeyFrameGapSeconds(weak), 0.5);

  // Waiting (the default): every wanted keyframe is inserted after the wait, weak or not.
  options.keyframe_weak_inliers = 0;
  options.mono_wait_for_mapping = true;
  const MonoRun waiting = trackMono(options, &busy);
  EXPECT_EQ(waiting.lost, 0);
  EXPECT_EQ(waiting.max_pending_jobs, 2u);
  EXPECT_GE(waiting.keyframes.size(), 2 * overdue_only.keyframes.size());
}

/// Keyframes of a mono-inertial run over longMonoSequence() with a busy mapper: whether each left
/// mapping jobs queued, before and after the inertial initialisation.
struct MonoInertialKeyFrames {
  std::vector<std::size_t> pending_before_init;
  std::vector<std::size_t> pending_after_init;
  std::vector<TimeNs> t_after_init;  ///< Times of the keyframes after the initialisation.
};

MonoInertialKeyFrames trackMonoInertial(bool wait_for_keyframe_ba,
                                        TrackerOptions options = TrackerOptions{}) {
  const auto source = openMonoSequence(true, true);
  FrontEnd front_end(FrontEndOptions{}, source->camera0(), std::nullopt);
  mapping::LocalMapperOptions mapping;
  mapping.triangulate = true;
  mapping.inertial = true;
  mapping.inertial_init.min_keyframes = 5;
  mapping.inertial_init.min_duration_s = 1.0;
  mapping.inertial_init.estimate_scale = true;
  mapping.inertial_init.min_scale_excitation = 0.05;  // the street flight is smooth
  options.mono_inertial_wait_for_keyframe_ba = wait_for_keyframe_ba;
  Tracker tracker(options, PyramidInfo{}, mapping, source->camera0(), std::nullopt, source->imu());
  ManualMappingSink busy(ManualMappingSink::kNeverOnItsOwn);
  tracker.setMappingSink(&busy);
  MonoInertialKeyFrames out;
  while (const auto bundle = source->next()) {
    const bool initialized = tracker.inertialInitialized();
    const TrackingResult result = tracker.track(front_end.build(*bundle));
    if (!result.keyframe || result.state != TrackingState::kTracking) continue;
    (initialized ? out.pending_after_init : out.pending_before_init).push_back(busy.pending());
    if (initialized) out.t_after_init.push_back(result.t_ns);
  }
  return out;
}

TEST(MonoTracker, MonoInertialWaitsForEachKeyFramesMappingJob) {
  // Before the inertial initialisation the next frames need the points the keyframe's job
  // triangulates, after it the IMU prediction starts from the keyframe's adjusted state: tracking
  // waits for each keyframe's mapping jobs, so none is left queued.
  const MonoInertialKeyFrames waiting = trackMonoInertial(true);
  ASSERT_FALSE(waiting.pending_before_init.empty());
  ASSERT_FALSE(waiting.pending_after_init.empty());
  for (const std::size_t pending : waiting.pending_before_init)
    EXPECT_EQ(pending, 0u);
  for (const std::size_t pending : waiting.pending_after_init)
    EXPECT_EQ(pending, 0u);
  // Without the wait the keyframe's jobs stay queued for the busy mapper (but at keyframes that
  // attempt the initialisation, which waits for it).
  const MonoInertialKeyFrames not_waiting = trackMonoInertial(false);
  ASSERT_FALSE(not_waiting.pending_after_init.empty());
  EXPECT_GT(*std::max_element(not_waiting.pending_before_init.begin(),
                              not_waiting.pending_before_init.end()),
            0u);
  for (const std::size_t pending : not_waiting.pending_after_init)
    EXPECT_GT(pending, 0u);
  std::printf(
      "keyframes before / after the initialisation: waiting %zu / %zu, not waiting %zu / %zu\n",
      waiting.pending_before_init.size(), waiting.pending_after_init.size(),
      not_waiting.pending_before_init.size(), not_waiting.pending_after_init.size());
}

TEST(MonoTracker, MonoInertialWeakTrackingTakesAKeyFrameBeforeTheMinimumInterval) {
  // Every frame tracks "weakly" (keyframe_weak_inliers above any inlier count): once the map is
  // inertial, keyframes come sooner than imu_min_keyframe_interval_s (ORB-SLAM3's rule); without
  // imu_weak_keyframes never sooner.
  TrackerOptions options;
  options.keyframe_weak_inliers = 100000;
  const MonoInertialKeyFrames weak = trackMonoInertial(true, options);
  ASSERT_GE(weak.t_after_init.size(), 3u);
  EXPECT_LT(minGapSeconds(weak.t_after_init), options.imu_min_keyframe_interval_s - 1e-6);
  options.imu_weak_keyframes = false;
  const MonoInertialKeyFrames spaced = trackMonoInertial(true, options);
  ASSERT_GE(spaced.t_after_init.size(), 3u);
  EXPECT_GE(minGapSeconds(spaced.t_after_init), options.imu_min_keyframe_interval_s - 1e-6);
  EXPECT_GT(weak.t_after_init.size(), spaced.t_after_init.size());
}

/// The first 1.5 s of the street sequence of issue 18 (street77: EuRoC V2_02 from 5 s, seed 77).
const std::filesystem::path& streetV202Sequence(const std::filesystem::path& v202_trajectory) {
  sim::SimulationOptions options =
      test::flightOptions(1.5, sim::SceneType::kStreet, sim::DynamicLevel::kNone, 77);
  options.motion.trajectory_file = v202_trajectory;
  options.motion.start_s = 5.0;
  return test::generatedSequence("tracker_test_street_v202", options);
}

/// The two-view map of a mono-inertial tracker on streetV202Sequence(): its keyframes' relative
/// rotation against the truth's [deg] and the frame it was built at.
struct TwoViewOutcome {
  double rotation_error_deg = -1.0;
  int frame = -1;
};

TwoViewOutcome monoInertialTwoView(const std::filesystem::path& v202_trajectory) {
  io::DatasetSourceOptions source_options;
  source_options.stereo = false;
  source_options.inertial = true;
  const auto source =
      io::openDataset(io::DatasetKind::kEuroc, streetV202Sequence(v202_trajectory), source_options);
  FrontEnd front_end(FrontEndOptions{}, source->camera0(), std::nullopt);
  mapping::LocalMapperOptions mapping;
  mapping.triangulate = true;
  Tracker tracker(TrackerOptions{}, PyramidInfo{}, mapping, source->camera0(), std::nullopt,
                  source->imu());
  std::map<TimeNs, SE3d> truth;
  TwoViewOutcome outcome;
  for (int frame = 0; const auto bundle = source->next(); ++frame) {
    if (bundle->T_w_b_gt) truth[bundle->t_ns] = *bundle->T_w_b_gt;
    if (tracker.track(front_end.build(*bundle)).state != TrackingState::kInitialized) continue;
    const std::vector<map::KeyFrameId> ids = tracker.map().keyFrameIds();
    std::vector<std::pair<TimeNs, SE3d>> poses;
    for (const map::KeyFrameId id : ids) {
      tracker.map().readKeyFrame(
          id, [&](const map::KeyFrame& kf) { poses.emplace_back(kf.t_ns, kf.T_w_b); });
    }
    const Eigen::Matrix3d estimated =
        poses.front().second.rotation().transpose() * poses.back().second.rotation();
    const Eigen::Matrix3d actual = truth.at(poses.front().first).rotation().transpose() *
                                   truth.at(poses.back().first).rotation();
    outcome.rotation_error_deg = rotationAngle(estimated.transpose() * actual) * 180.0 / M_PI;
    outcome.frame = frame;
    break;
  }
  return outcome;
}

TEST(MonoTracker, MonoInertialTwoViewMapAgreesWithTheTruthOnTheStreet) {
  // One frame after the reference the homography explained the street's flow with a rotation
  // 1.7 deg off: the bent map lost track at the inertial initialisation (issue 18, item 10).
  // The gyroscope now refuses it and a later frame (more parallax) builds the map.
  SUPERDYNA_REQUIRE_SHARED(v202, "data/trajectories/euroc/V2_02_medium.txt");
  const TwoViewOutcome outcome = monoInertialTwoView(v202);
  std::cout << "street two-view map at frame " << outcome.frame << ": rotation error "
            << outcome.rotation_error_deg << " deg\n";
  ASSERT_GE(outcome.frame, 0);
  EXPECT_LT(outcome.rotation_error_deg, 1.0);
}

TEST(MonoTracker, KeyFramesKeepTheMinimumIntervalUnlessTrackingIsWeak) {
  TrackerOptions options;
  options.keyframe_tracked_ratio = 0.9;
  options.keyframe_min_interval_s = 0.25;
  options.keyframe_weak_inliers = 0;
  const MonoRun spaced = trackMono(options, nullptr);
  EXPECT_EQ(spaced.lost, 0);
  ASSERT_GE(spaced.keyframes.size(), 3u);
  EXPECT_GE(minKeyFrameGapSeconds(spaced), 0.25 - 1e-6);
  // An idle mapper (or none) and no minimum interval: the tracked-ratio test fires more often.
  options.keyframe_min_interval_s = 0.0;
  ManualMappingSink idle(0);
  const MonoRun dense = trackMono(options, &idle);
  EXPECT_EQ(dense.lost, 0);
  EXPECT_GT(dense.keyframes.size(), spaced.keyframes.size());
  EXPECT_LT(minKeyFrameGapSeconds(dense), 0.25);
}

/// An 8 s street flight whose accelerometer bias wanders 33 times faster than the simulator's
/// default (0.1 m/s^3/sqrt(Hz)): the biases at the inertial initialisation do not last, so a
/// velocity carried by the IMU alone drifts within seconds.
const std::filesystem::path& wanderingBiasSequence() {
  sim::SimulationOptions options =
      test::flightOptions(8.0, sim::SceneType::kStreet, sim::DynamicLevel::kNone, 7);
  options.imu.accelerometer_random_walk = 0.1;
  return test::generatedSequence("tracker_test_wandering_bias", options);
}

/// Distances between predicted and tracked positions after the inertial initialisation [m].
struct PredictionRun {
  int lost = 0;
  bool initialized = false;
  std::vector<double> prediction_m;
  /// The distance at the frame of the inertial initialisation, whose map moved into the
  /// gravity-aligned frame [m]; -1 if none.
  double initialization_prediction_m = -1.0;
};

/// Stereo-inertial tracking of wanderingBiasSequence() with the mapping jobs to `sink`.
PredictionRun trackStereoInertial(MappingSink& sink) {
  const auto source = io::openDataset(io::DatasetKind::kEuroc, wanderingBiasSequence(), {});
  FrontEnd front_end(FrontEndOptions{}, source->camera0(), source->camera1());
  Tracker tracker(TrackerOptions{}, PyramidInfo{}, mapping::LocalMapperOptions{}, source->camera0(),
                  source->camera1(), source->imu());
  tracker.setMappingSink(&sink);
  PredictionRun run;
  while (const auto bundle = source->next()) {
    const bool initialized = tracker.inertialInitialized();  // before this frame
    const TrackingResult result = tracker.track(front_end.build(*bundle));
    if (result.state == TrackingState::kLost) ++run.lost;
    if (result.state != TrackingState::kTracking || result.from_reference) continue;
    const double offset = (result.T_w_b.t - result.T_w_predicted.t).norm();
    if (result.world_change && !initialized) run.initialization_prediction_m = offset;
    if (initialized) run.prediction_m.push_back(offset);
  }
  run.initialized = tracker.inertialInitialized();
  return run;
}

TEST(StereoInertialTracker, PredictsFromEstimatedStatesWhileTheMapperLagsBehind) {
  // The IMU prediction starts from a keyframe's velocity and biases. A keyframe gets them from
  // the prediction it was inserted with, and local inertial BA estimates them later. A mapper a
  // keyframe behind left the tracker taking them from keyframes whose velocity was only a
  // prediction from the one before, and so on: no estimate ever reached the prediction, and on a
  // KITTI-speed street the velocity drifted by metres per second until tracking failed
  // (issue 18). They must come from the newest estimated keyframe. Measured (this build, the
  // deterministic sinks here): median offset lagging / in time 3.7 with the fix, 5.2 without.
  ManualMappingSink in_time(0);
  const PredictionRun prompt = trackStereoInertial(in_time);
  ManualMappingSink lagging(3);
  const PredictionRun lagged = trackStereoInertial(lagging);
  ASSERT_TRUE(prompt.initialized);
  ASSERT_TRUE(lagged.initialized);
  ASSERT_GE(lagged.prediction_m.size(), 40u);
  EXPECT_EQ(prompt.lost, 0);
  EXPECT_EQ(lagged.lost, 0);
  const double prompt_median = eval::median(prompt.prediction_m);
  const double lagged_median = eval::median(lagged.prediction_m);
  std::cout << "predicted - tracked position after the inertial initialisation, median: mapper "
            << "in time " << prompt_median << " m, a keyframe behind " << lagged_median
            << " m; at the initialisation " << prompt.initialization_prediction_m << " m\n";
  EXPECT_LT(lagged_median, 4.5 * prompt_median);
  // The prediction moves into the gravity-aligned frame with the map (0.18 m off when it did not).
  EXPECT_GE(prompt.initialization_prediction_m, 0.0);
  EXPECT_LT(prompt.initialization_prediction_m, 0.05);
}

TEST(TrackerOptions, RejectsBadValues) {
  TrackerOptions options;
  options.min_inliers = 2;
  test::expectError<OptionError>([&] { options.validate(); }, {"tracker.min_inliers"});
  options = {};
  options.keyframe_tracked_ratio = 1.5;
  test::expectError<OptionError>([&] { options.validate(); }, {"tracker.keyframe_tracked_ratio"});
  options = {};
  options.keyframe_min_interval_s = -0.1;
  test::expectError<OptionError>([&] { options.validate(); }, {"tracker.keyframe_min_interval_s"});
  options = {};
  options.keyframe_weak_inliers = -1;
  test::expectError<OptionError>([&] { options.validate(); }, {"tracker.keyframe_weak_inliers"});
  options = {};
  options.projection.radius_px = 0.0;
  test::expectError<OptionError>([&] { makeTracker(options); }, {"radius"});
  FrontEndOptions front_end;
  front_end.features.orb.features = 0;
  test::expectError<OptionError>([&] { makeFrontEnd(front_end); }, {"features"});
}

TEST(Tracker, BlankImagesDoNotInitialiseOrCrash) {
  Tracker tracker = makeTracker();
  FrontEnd front_end = makeFrontEnd();
  const sim::RigOptions rig;
  for (int i = 0; i < 3; ++i) {
    sensors::FrameBundle frame;
    frame.index = static_cast<std::size_t>(i);
    frame.t_ns = secondsToNs(0.05 * i);
    frame.image0 = cv::Mat::zeros(rig.height, rig.width, CV_8UC1);
    frame.image1 = frame.image0.clone();
    const TrackingResult result = tracker.track(front_end.build(frame));
    EXPECT_EQ(result.state, TrackingState::kLost);
    EXPECT_FALSE(result.keyframe);
    EXPECT_TRUE(result.T_w_b.t.isZero());
  }
}

/// A frame seeing the points `p_w` (world) from body pose T_w_b through the simulated rig: one
/// left keypoint per point at its exact projection, descriptor row k of `descriptors`; with
/// `stereo`, depth and right observation too. `decoys` adds, for the listed points, a second
/// keypoint with the same descriptor at `decoy_pixels`.
Frame syntheticFrame(TimeNs t_ns, const SE3d& T_w_b, const std::vector<Eigen::Vector3d>& p_w,
                     const cv::Mat& descriptors, bool stereo,
                     const std::vector<std::pair<int, Eigen::Vector2d>>& decoys = {}) {
  const sim::RigOptions rig;
  const CameraModel camera = rig.cameraModel();
  const SE3d T_c0_w = (T_w_b * rig.T_b_c0()).inverse();
  const SE3d T_c1_w = (T_w_b * rig.T_b_c1()).inverse();
  Frame frame;
  frame.t_ns = t_ns;
  frame.features.descriptor_type = features::DescriptorType::kFloat;
  frame.features.image_size = {rig.width, rig.height};
  std::vector<cv::Mat> rows;
  const auto add = [&](const Eigen::Vector2d& pixel, int row) {
    features::Keypoint k;
    k.pixel = pixel;
    k.angle = -1.0f;
    frame.features.keypoints.push_back(k);
    rows.push_back(descriptors.row(row));
    frame.normalized.push_back(
        Eigen::Vector2d((pixel.x() - rig.cx) / rig.fx, (pixel.y() - rig.cy) / rig.fy));
  };
  for (std::size_t k = 0; k < p_w.size(); ++k) {
    const Eigen::Vector3d p_c0 = T_c0_w * p_w[k];
    add(*camera.project(p_c0), static_cast<int>(k));
    frame.depth_m.push_back(stereo ? p_c0.z() : -1.0);
    frame.p_c0.push_back(p_c0);
    const Eigen::Vector3d p_c1 = T_c1_w * p_w[k];
    frame.right_normalized.push_back(
        stereo ? std::optional<Eigen::Vector2d>(p_c1.head<2>() / p_c1.z()) : std::nullopt);
  }
  for (const auto& [k, pixel] : decoys) {
    add(pixel, k);
    frame.depth_m.push_back(-1.0);
    frame.p_c0.push_back(Eigen::Vector3d::Zero());
    frame.right_normalized.push_back(std::nullopt);
  }
  cv::vconcat(rows, frame.features.descriptors);
  return frame;
}

TEST(Tracker, SecondSearchFromTheFirstPoseRecoversAmbiguousMatches) {
  // 200 points 3-5 m ahead with random unit descriptors. The second frame moved 0.1 m sideways
  // (about 10-15 px of image motion) but, without a motion model, is predicted where the first
  // was. Every even point has a decoy with its own descriptor at the pixel the prediction puts
  // it at: the ratio test rejects both candidates in the 15 px search, so only the odd points
  // match. Searching again within 3 px of the projections from that first pose separates true
  // keypoints from decoys and recovers the even points.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> x(-2.0, 2.0), y(-1.2, 1.2), z(3.0, 5.0);
  std::normal_distribution<float> normal;
  const sim::RigOptions rig;
  const SE3d T_w_c0 = rig.T_b_c0();  // body at the world origin
  std::vector<Eigen::Vector3d> p_w;
  cv::Mat descriptors(200, 64, CV_32FC1);
  for (int k = 0; k < 200; ++k) {
    p_w.push_back(T_w_c0 * Eigen::Vector3d(x(rng), y(rng), z(rng)));
    for (int c = 0; c < 64; ++c)
      descriptors.at<float>(k, c) = normal(rng);
    cv::normalize(descriptors.row(k), descriptors.row(k));
  }
  const SE3d T_w_b1;
  const SE3d T_w_b2 = T_w_b1 * SE3d(Eigen::Quaterniond::Identity(),
                                    rig.T_b_c0().rotation() * Eigen::Vector3d(0.1, 0.0, 0.0));
  const Frame first = syntheticFrame(0, T_w_b1, p_w, descriptors, true);
  std::vector<std::pair<int, Eigen::Vector2d>> decoys;
  for (int k = 0; k < 200; k += 2)
    decoys.emplace_back(k, first.features.keypoints[static_cast<std::size_t>(k)].pixel);
  const Frame second = syntheticFrame(secondsToNs(0.05), T_w_b2, p_w, descriptors, false, decoys);

  const auto inliersOfSecond = [&](double refine_radius_px) {
    TrackerOptions options;
    options.refine_radius_px = refine_radius_px;
    options.reference_matching.enabled = false;  // this test is about the projection search
    Tracker tracker = makeTracker(options);
    EXPECT_EQ(tracker.track(first).state, TrackingState::kInitialized);
    const TrackingResult result = tracker.track(second);
    EXPECT_EQ(result.state, TrackingState::kTracking);
    EXPECT_LT((result.T_w_b.t - T_w_b2.t).norm(), 0.01);
    return result.inliers;
  };
  const int single = inliersOfSecond(0.0);
  EXPECT_GE(single, 90);
  EXPECT_LE(single, 105);
  EXPECT_GE(inliersOfSecond(3.0), 195);
  TrackerOptions bad;
  bad.refine_radius_px = -1.0;
  test::expectError<OptionError>([&] { bad.validate(); }, {"tracker.refine_radius_px"});
}

/// `count` points 3-5 m ahead of the body at the world origin, with random unit descriptors.
std::pair<std::vector<Eigen::Vector3d>, cv::Mat> randomScene(int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> x(-2.0, 2.0), y(-1.2, 1.2), z(3.0, 5.0);
  std::normal_distribution<float> normal;
  const sim::RigOptions rig;
  std::vector<Eigen::Vector3d> p_w;
  cv::Mat descriptors(count, 64, CV_32FC1);
  for (int k = 0; k < count; ++k) {
    p_w.push_back(rig.T_b_c0() * Eigen::Vector3d(x(rng), y(rng), z(rng)));
    for (int c = 0; c < 64; ++c)
      descriptors.at<float>(k, c) = normal(rng);
    cv::normalize(descriptors.row(k), descriptors.row(k));
  }
  return {p_w, descriptors};
}

TEST(Tracker, FirstFrameOfAMapIsTrackedFromTheReferenceKeyFrame) {
  // The second frame of a map moved 0.25 m sideways (30-70 px of image motion); with no motion
  // model yet it is predicted where the first frame was. Each point has a look-alike keypoint
  // (descriptor + small noise, as neighbouring XFeat keypoints are) exactly where that prediction
  // projects it. The projection search takes the look-alikes and confirms the wrong pose; matching
  // the reference keyframe without a prediction and PnP find the true one.
  const auto [p_w, descriptors] = randomScene(200, 11);
  const sim::RigOptions rig;
  const SE3d T_w_b2(Eigen::Quaterniond::Identity(),
                    rig.T_b_c0().rotation() * Eigen::Vector3d(0.25, 0.0, 0.0));
  const Frame first = syntheticFrame(0, SE3d(), p_w, descriptors, true);
  std::mt19937 rng(3);
  std::normal_distribution<float> normal(0.0f, 0.03f);
  cv::Mat look_alikes = descriptors.clone();
  for (int k = 0; k < look_alikes.rows; ++k) {
    for (int c = 0; c < look_alikes.cols; ++c)
      look_alikes.at<float>(k, c) += normal(rng);
    cv::normalize(look_alikes.row(k), look_alikes.row(k));
  }
  cv::Mat both;
  cv::vconcat(descriptors, look_alikes, both);
  std::vector<std::pair<int, Eigen::Vector2d>> decoys;
  for (int k = 0; k < 200; ++k)
    decoys.emplace_back(200 + k, first.features.keypoints[static_cast<std::size_t>(k)].pixel);
  const Frame second = syntheticFrame(secondsToNs(0.05), T_w_b2, p_w, both, false, decoys);

  const auto trackSecond = [&](bool reference_matching) {
    TrackerOptions options;
    options.reference_matching.enabled = reference_matching;
    Tracker tracker = makeTracker(options);
    EXPECT_EQ(tracker.track(first).state, TrackingState::kInitialized);
    return tracker.track(second);
  };
  const TrackingResult without = trackSecond(false);
  EXPECT_FALSE(without.from_reference);
  EXPECT_GT((without.T_w_b.t - T_w_b2.t).norm(), 0.2);  // stuck at the prediction
  const TrackingResult with = trackSecond(true);
  EXPECT_EQ(with.state, TrackingState::kTracking);
  EXPECT_TRUE(with.from_reference);
  EXPECT_LT((with.T_w_b.t - T_w_b2.t).norm(), 1e-3);
  EXPECT_GE(with.inliers, 195);
}

TEST(Tracker, SearchesMapPointsAtTheOctavePredictedFromTheirDistance) {
  // 200 points 6.2-8 m ahead, seen at octave 0 by the first frame (the map's only keyframe). The
  // camera then moves 1 m forward per frame; at 2 m closer the points appear 1.3-1.5 times larger
  // and the extractor finds them at octave 2, while a look-alike keypoint (same descriptor) lies
  // 3 px from each of them at octave 0. Searching octaves [L - 1, L] about the octave L of the
  // point's first observation (0) finds only the look-alikes; about the octave predicted from
  // the distance (2 or 3) it finds the points themselves.
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> x(-2.0, 2.0), y(-1.2, 1.2), z(6.2, 8.0), angle(0, 6.28);
  std::normal_distribution<float> normal;
  const sim::RigOptions rig;
  std::vector<Eigen::Vector3d> p_w;
  cv::Mat descriptors(200, 64, CV_32FC1);
  for (int k = 0; k < 200; ++k) {
    p_w.push_back(rig.T_b_c0() * Eigen::Vector3d(x(rng), y(rng), z(rng)));
    for (int c = 0; c < 64; ++c)
      descriptors.at<float>(k, c) = normal(rng);
    cv::normalize(descriptors.row(k), descriptors.row(k));
  }
  const auto forward = [&](double metres) {
    return SE3d(Eigen::Quaterniond::Identity(),
                rig.T_b_c0().rotation() * Eigen::Vector3d(0.0, 0.0, metres));
  };
  const Frame first = syntheticFrame(0, forward(0.0), p_w, descriptors, true);
  const Frame second = syntheticFrame(secondsToNs(0.05), forward(1.0), p_w, descriptors, false);
  const Frame plain = syntheticFrame(secondsToNs(0.1), forward(2.0), p_w, descriptors, false);
  std::vector<std::pair<int, Eigen::Vector2d>> decoys;
  for (int k = 0; k < 200; ++k) {
    const double a = angle(rng);
    decoys.emplace_back(k, plain.features.keypoints[static_cast<std::size_t>(k)].pixel +
                               3.0 * Eigen::Vector2d(std::cos(a), std::sin(a)));
  }
  Frame third = syntheticFrame(secondsToNs(0.1), forward(2.0), p_w, descriptors, false, decoys);
  for (int k = 0; k < 200; ++k)
    third.features.keypoints[static_cast<std::size_t>(k)].octave = 2;

  const auto trackThird = [&](bool predict_octave) {
    TrackerOptions options;
    options.predict_octave = predict_octave;
    options.projection.min_octave_offset = -1;
    options.projection.max_octave_offset = 0;
    options.keyframe_max_interval_s = 100.0;  // the first frame stays the only keyframe
    options.keyframe_min_tracked = 0;
    options.keyframe_tracked_ratio = 0.1;
    Tracker tracker = makeTracker(options);
    EXPECT_EQ(tracker.track(first).state, TrackingState::kInitialized);
    EXPECT_EQ(tracker.track(second).state, TrackingState::kTracking);
    return tracker.track(third);
  };
  const TrackingResult predicted = trackThird(true);
  EXPECT_EQ(predicted.state, TrackingState::kTracking);
  EXPECT_LT((predicted.T_w_b.t - forward(2.0).t).norm(), 1e-3);
  EXPECT_GE(predicted.inliers, 195);
  const TrackingResult observed = trackThird(false);
  EXPECT_LT(observed.inliers, 100);
}

TEST(Tracker, KeyFrameKeypointsWhoseUndistortionFailedStayInvalid) {
  // The front end gives NaN normalised coordinates (and no stereo) where undistortion failed. The
  // keyframe must keep them invalid rather than place them at the principal point (0, 0), where
  // triangulation and BA would take them for real observations.
  const auto [p_w, descriptors] = randomScene(200, 5);
  Frame first = syntheticFrame(0, SE3d(), p_w, descriptors, true);
  constexpr std::size_t kFailed = 10;
  for (std::size_t k = 0; k < kFailed; ++k) {
    first.normalized[k].setConstant(std::numeric_limits<double>::quiet_NaN());
    first.depth_m[k] = -1.0;
    first.right_normalized[k] = std::nullopt;
  }
  Tracker tracker = makeTracker();
  ASSERT_EQ(tracker.track(first).state, TrackingState::kInitialized);
  const std::vector<map::KeyFrameId> ids = tracker.map().keyFrameIds();
  ASSERT_EQ(ids.size(), 1u);
  std::vector<bool> valid;
  std::size_t observed_invalid = 0;
  tracker.map().readKeyFrame(ids.front(), [&](const map::KeyFrame& kf) {
    for (std::size_t k = 0; k < kf.size(); ++k) {
      valid.push_back(kf.keypoints[k].valid());
      if (!kf.keypoints[k].valid() && kf.map_points[k] != map::kNoMapPoint) ++observed_invalid;
    }
  });
  ASSERT_EQ(valid.size(), p_w.size());
  EXPECT_EQ(std::count(valid.begin(), valid.end(), false), static_cast<long>(kFailed));
  for (std::size_t k = 0; k < kFailed; ++k)
    EXPECT_FALSE(valid[k]) << k;
  EXPECT_EQ(observed_invalid, 0u);
  EXPECT_EQ(tracker.map().consistencyError(), "");
}

TEST(ReferenceMatching, PoseFromDescriptorsAloneDespiteOutliers) {
  // 150 points seen from a pose 0.6 m and 20 degrees away from the origin; 100 more keypoints with
  // random descriptors that match nothing, and 20 true matches moved 30 px (wrong positions).
  const auto [p_w, descriptors] = randomScene(150, 5);
  const sim::RigOptions rig;
  const SE3d T_w_b(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.35, Eigen::Vector3d(0.2, 1.0, 0.1).normalized())),
      Eigen::Vector3d(0.3, -0.4, 0.35));
  std::vector<std::pair<int, Eigen::Vector2d>> clutter;
  const auto [unused, noise] = randomScene(100, 6);
  cv::Mat rows;
  cv::vconcat(descriptors, noise, rows);
  for (int k = 0; k < 100; ++k)
    clutter.emplace_back(150 + k, Eigen::Vector2d(5.0 + 7.0 * k, 40.0 + 3.0 * k));
  Frame frame = syntheticFrame(0, T_w_b, p_w, rows, false, clutter);
  for (std::size_t k = 0; k < 20; ++k) {
    frame.features.keypoints[k].pixel.x() += 30.0;
    frame.normalized[k].x() += 30.0 / rig.fx;
  }
  ReferenceView view;
  view.features.descriptor_type = features::DescriptorType::kFloat;
  view.features.descriptors = descriptors;
  view.features.keypoints.resize(150);
  view.p_w = p_w;

  ReferenceMatchingOptions options;
  const std::optional<ReferencePose> pose =
      poseFromReference(frame, view, rig.T_b_c0(), rig.fx, options);
  ASSERT_TRUE(pose.has_value());
  EXPECT_EQ(pose->matches, 150);  // the clutter matches nothing
  EXPECT_EQ(pose->inliers, 130);  // the moved 20 are RANSAC outliers
  EXPECT_LT((pose->T_w_b.t - T_w_b.t).norm(), 1e-6);
  EXPECT_LT((pose->T_w_b.inverse() * T_w_b).q.angularDistance(Eigen::Quaterniond::Identity()),
            1e-6);
  // Too few points for the required support: no pose rather than a guess.
  options.min_inliers = 200;
  EXPECT_FALSE(poseFromReference(frame, view, rig.T_b_c0(), rig.fx, options).has_value());
  options.ransac_threshold_px = 0.0;
  test::expectError<OptionError>([&] { options.validate(); },
                                 {"tracker.reference_ransac_threshold_px"});
}

}  // namespace
}  // namespace superdyna::tracking

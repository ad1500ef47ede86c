#include "superdyna/mapping/keyframe_culling.h"

#include <gtest/gtest.h>

#include <cmath>

#include "superdyna/core/error.h"
#include "superdyna/mapping/keyframe_preintegration.h"

namespace superdyna::mapping {
namespace {

constexpr TimeNs kStartNs = 1'000'000'000'000;
constexpr TimeNs kImuPeriodNs = 5'000'000;  // 200 Hz

/// A varying IMU signal at 200 Hz over [kStartNs - 10 ms, end_ns + 10 ms].
std::vector<sensors::ImuSample> imuSignal(TimeNs end_ns) {
  std::vector<sensors::ImuSample> samples;
  for (TimeNs t = kStartNs - 2 * kImuPeriodNs; t <= end_ns + 2 * kImuPeriodNs; t += kImuPeriodNs) {
    const double s = nsToSeconds(t - kStartNs);
    samples.push_back({t, Eigen::Vector3d(0.3 * std::sin(3 * s), 0.2, -0.4 * std::cos(2 * s)),
                       Eigen::Vector3d(1.0 + std::sin(5 * s), -0.5, 9.81 + 0.3 * std::cos(4 * s))});
  }
  return samples;
}

/// The samples bracketing [t0, t1].
std::vector<sensors::ImuSample> bracketing(const std::vector<sensors::ImuSample>& all, TimeNs t0,
                                           TimeNs t1) {
  std::vector<sensors::ImuSample> out;
  for (std::size_t k = 0; k < all.size(); ++k) {
    const bool next_after_start = k + 1 < all.size() && all[k + 1].t_ns > t0;
    const bool previous_before_end = k > 0 && all[k - 1].t_ns < t1;
    if (next_after_start && previous_before_end) out.push_back(all[k]);
  }
  return out;
}

/// `count` keyframes `spacing_ns` apart (times not on the IMU grid) that all observe the same 50
/// points at octave 0, with the IMU samples between consecutive ones.
struct CullingScene {
  map::Map map;
  std::vector<map::KeyFrameId> ids;
  std::vector<TimeNs> times;
  std::vector<sensors::ImuSample> samples;
};

std::unique_ptr<CullingScene> makeScene(int count, TimeNs spacing_ns) {
  auto scene = std::make_unique<CullingScene>();
  for (int k = 0; k < count; ++k)
    scene->times.push_back(kStartNs + 1'234'567 + k * spacing_ns);
  scene->samples = imuSignal(scene->times.back());
  std::vector<map::MapPointId> points;
  for (int p = 0; p < 50; ++p) {
    map::MapPoint point;
    point.p_w = Eigen::Vector3d(0.1 * p - 2.5, 0.05 * p, 5.0);
    points.push_back(scene->map.addMapPoint(point));
  }
  for (int k = 0; k < count; ++k) {
    map::KeyFrame kf;
    kf.t_ns = scene->times[static_cast<std::size_t>(k)];
    kf.T_w_b.t = Eigen::Vector3d(0.01 * k, 0.0, 0.0);
    kf.keypoints.resize(points.size());
    if (k > 0) {
      kf.imu_from_previous =
          bracketing(scene->samples, scene->times[static_cast<std::size_t>(k) - 1], kf.t_ns);
    }
    const map::KeyFrameId id = scene->map.addKeyFrame(std::move(kf));
    for (std::size_t p = 0; p < points.size(); ++p)
      scene->map.addObservation(points[p], id, static_cast<int>(p));
    scene->ids.push_back(id);
  }
  return scene;
}

TEST(KeyFrameCullingTest, RedundantShareCountsObserversAtSameOrFinerScale) {
  auto scene = makeScene(4, 100'000'000);
  EXPECT_DOUBLE_EQ(redundantPointShare(scene->map, scene->ids[1], 3), 1.0);
  EXPECT_DOUBLE_EQ(redundantPointShare(scene->map, scene->ids[1], 4), 0.0);
}

TEST(KeyFrameCullingTest, RemovesARedundantKeyFrameAndMergesItsPreintegration) {
  auto scene = makeScene(5, 100'000'000);  // 0.1 s apart
  imu::ImuNoise noise;
  KeyFrameCullingOptions options;
  options.max_candidates = 1;  // examine only the best covisible one (ties: smallest id)
  const std::vector<map::KeyFrameId> culled =
      cullRedundantKeyFrames(scene->map, scene->ids.back(), options, CullingImu{true, 0});
  // Keyframe 0 is the first of the map, so the candidate examined is keyframe 0: kept.
  EXPECT_TRUE(culled.empty());

  options.max_candidates = 2;
  const std::vector<map::KeyFrameId> second =
      cullRedundantKeyFrames(scene->map, scene->ids.back(), options, CullingImu{true, 0});
  ASSERT_EQ(second, std::vector<map::KeyFrameId>{scene->ids[1]});
  EXPECT_FALSE(scene->map.hasKeyFrame(scene->ids[1]));
  EXPECT_EQ(scene->map.consistencyError(), "");

  // The successor now links to keyframe 0 and holds the samples of both gaps.
  const map::KeyFrame successor = *scene->map.keyFrame(scene->ids[2]);
  EXPECT_EQ(successor.previous, scene->ids[0]);
  const std::vector<sensors::ImuSample> expected =
      bracketing(scene->samples, scene->times[0], scene->times[2]);
  ASSERT_EQ(successor.imu_from_previous.size(), expected.size());
  for (std::size_t k = 0; k < expected.size(); ++k)
    EXPECT_EQ(successor.imu_from_previous[k].t_ns, expected[k].t_ns);

  // Merged preintegration == integrating the concatenated samples over the whole gap.
  const imu::Bias bias{Eigen::Vector3d(0.01, -0.02, 0.005), Eigen::Vector3d(0.1, 0.05, -0.08)};
  const auto merged = preintegrateFromPrevious(successor, scene->times[0], bias, noise);
  ASSERT_TRUE(merged);
  imu::Preintegration direct(bias, noise);
  direct.integrateBetween(scene->samples, scene->times[0], scene->times[2]);
  EXPECT_DOUBLE_EQ(merged->deltaTime(), direct.deltaTime());
  EXPECT_TRUE(merged->deltaRotation().isApprox(direct.deltaRotation(), 1e-14));
  EXPECT_TRUE(merged->deltaVelocity().isApprox(direct.deltaVelocity(), 1e-14));
  EXPECT_TRUE(merged->deltaPosition().isApprox(direct.deltaPosition(), 1e-14));
  EXPECT_TRUE(merged->covariance().isApprox(direct.covariance(), 1e-12));
  EXPECT_NEAR(merged->deltaTime(), 0.2, 1e-12);

  // The cache follows the new link.
  KeyFramePreintegrations cache(noise);
  const imu::Preintegration* cached = cache.fromPrevious(scene->map, scene->ids[2]);
  ASSERT_NE(cached, nullptr);
  EXPECT_NEAR(cached->deltaTime(), 0.2, 1e-12);
}

TEST(KeyFrameCullingTest, KeepsKeyFramesWhoseRemovalLeavesALongImuGap) {
  auto scene = makeScene(5, 300'000'000);  // 0.3 s apart: removal leaves 0.6 s
  KeyFrameCullingOptions options;
  EXPECT_TRUE(
      cullRedundantKeyFrames(scene->map, scene->ids.back(), options, CullingImu{true, 0}).empty());
  // After the inertial initialisation, keyframes older than the window may leave 3 s gaps.
  const std::vector<map::KeyFrameId> culled =
      cullRedundantKeyFrames(scene->map, scene->ids.back(), options, CullingImu{true, 2});
  EXPECT_FALSE(culled.empty());
  for (const map::KeyFrameId id : culled) {
    EXPECT_NE(id, scene->ids.front());
    EXPECT_LT(id, scene->ids[3]);  // never the newest ones
  }
  // Without IMU no gap rule applies.
  auto visual = makeScene(5, 300'000'000);
  EXPECT_FALSE(cullRedundantKeyFrames(visual->map, visual->ids.back(), options).empty());
}

TEST(KeyFrameCullingTest, KeyFramesLongBehindTheNewestMayLeaveLongerGaps) {
  // 12 keyframes 5 s apart: removing one leaves 10 s, beyond the 3 s of max_gap_inertial_s.
  auto scene = makeScene(12, 5'000'000'000);
  KeyFrameCullingOptions options;
  options.max_candidates = 20;
  options.old_after_s = 32.0;
  options.max_gap_old_s = 10.5;
  const std::vector<map::KeyFrameId> culled =
      cullRedundantKeyFrames(scene->map, scene->ids.back(), options, CullingImu{true, 2});
  ASSERT_FALSE(culled.empty());
  // Only keyframes made more than 32 s before the newest (55 s): ids 1..4 (5, 10, 15, 20 s);
  // culled from the oldest on, each removal widens its successor's gap (1 and 3 go, 2 and 4
  // would then leave 15 s).
  EXPECT_EQ(culled, (std::vector<map::KeyFrameId>{scene->ids[1], scene->ids[3]}));
  EXPECT_EQ(scene->map.consistencyError(), "");
  // With the old tier as short as the inertial one nothing goes.
  auto again = makeScene(12, 5'000'000'000);
  options.max_gap_old_s = options.max_gap_inertial_s;
  EXPECT_TRUE(
      cullRedundantKeyFrames(again->map, again->ids.back(), options, CullingImu{true, 2}).empty());
}

TEST(KeyFramePreintegrationsTest, KeepsNoStepsAndIntegratesAgainWhenTheBiasMovedFar) {
  auto scene = makeScene(3, 100'000'000);
  const imu::ImuNoise noise;
  KeyFramePreintegrations cache(noise);
  const imu::Preintegration* first = cache.fromPrevious(scene->map, scene->ids[2]);
  ASSERT_NE(first, nullptr);
  EXPECT_TRUE(first->steps().empty());  // the keyframe's samples are kept once, by the map
  EXPECT_TRUE(first->linearizationBias().bg.isZero());
  const Eigen::Vector3d dV_zero = first->deltaVelocity();

  // A small bias change of the predecessor: first-order corrections, the same entry.
  const Eigen::Vector3d v = Eigen::Vector3d::Zero();
  scene->map.setKeyFrameInertialState(scene->ids[1], v, Eigen::Vector3d(0.002, 0, 0), v);
  const imu::Preintegration* near = cache.fromPrevious(scene->map, scene->ids[2]);
  ASSERT_NE(near, nullptr);
  EXPECT_TRUE(near->linearizationBias().bg.isZero());
  EXPECT_EQ(near->deltaVelocity(), dV_zero);

  // Beyond the threshold: integrated again from the samples at the new bias, as re-integrating
  // the steps would.
  const imu::Bias far{Eigen::Vector3d(0.05, -0.02, 0.01), Eigen::Vector3d(0.1, 0.0, -0.1)};
  scene->map.setKeyFrameInertialState(scene->ids[1], v, far.bg, far.ba);
  const imu::Preintegration* moved = cache.fromPrevious(scene->map, scene->ids[2]);
  ASSERT_NE(moved, nullptr);
  EXPECT_EQ(moved->linearizationBias().bg, far.bg);
  imu::Preintegration expected(imu::Bias{}, noise);
  expected.integrateBetween(scene->samples, scene->times[1], scene->times[2]);
  expected.reintegrate(far);
  EXPECT_TRUE(moved->deltaRotation().isApprox(expected.deltaRotation(), 1e-14));
  EXPECT_TRUE(moved->deltaVelocity().isApprox(expected.deltaVelocity(), 1e-14));
  EXPECT_TRUE(moved->deltaPosition().isApprox(expected.deltaPosition(), 1e-14));
  EXPECT_TRUE(moved->covariance().isApprox(expected.covariance(), 1e-12));
  EXPECT_TRUE(moved->J_P_bg().isApprox(expected.J_P_bg(), 1e-12));
}

TEST(KeyFramePreintegrationsTest, AThinnedLongLinkPreintegratesLikeItsFullSamples) {
  // 60 s at 200 Hz of a rig turning and accelerating smoothly, as a link between two keyframes
  // far behind the newest that culling lengthened, thinned to the map's 1024 samples.
  std::vector<sensors::ImuSample> full;
  for (TimeNs t = 0; t <= secondsToNs(60.0); t += secondsToNs(0.005)) {
    const double s = nsToSeconds(t);
    sensors::ImuSample sample;
    sample.t_ns = t;
    sample.gyro = Eigen::Vector3d(0.1 * std::sin(0.5 * s), 0.2, 0.05 * std::cos(0.2 * s));
    sample.accel = Eigen::Vector3d(0.3 * std::sin(0.4 * s), 9.81, std::cos(0.3 * s));
    full.push_back(sample);
  }
  const std::vector<sensors::ImuSample> thinned = map::thinImuSamples(full, 1024);
  ASSERT_EQ(thinned.size(), 1024u);
  const imu::ImuNoise noise;
  imu::Preintegration from_full(imu::Bias{}, noise);
  from_full.integrateBetween(full, 0, secondsToNs(60.0));
  imu::Preintegration from_thinned(imu::Bias{}, noise);
  from_thinned.integrateBetween(thinned, 0, secondsToNs(60.0));
  const double rotation_error =
      Eigen::AngleAxisd(from_full.deltaRotation().transpose() * from_thinned.deltaRotation())
          .angle();
  EXPECT_LT(rotation_error, 1e-4);  // rad, over 12 rad turned
  EXPECT_LT((from_thinned.deltaVelocity() - from_full.deltaVelocity()).norm(),
            1e-3 * from_full.deltaVelocity().norm());
  EXPECT_LT((from_thinned.deltaPosition() - from_full.deltaPosition()).norm(),
            1e-3 * from_full.deltaPosition().norm());
  // The noise model integrates the same white noise over the same time: the same covariance.
  EXPECT_TRUE(from_thinned.covariance().isApprox(from_full.covariance(), 0.05));
}

TEST(KeyFrameCullingTest, RejectsInvalidOptions) {
  KeyFrameCullingOptions options;
  options.redundancy = 0.0;
  EXPECT_THROW(options.validate(), OptionError);
  options = {};
  options.keep_newest = 0;
  EXPECT_THROW(options.validate(), OptionError);
  options = {};
  options.max_gap_old_s = options.max_gap_inertial_s - 0.1;
  EXPECT_THROW(options.validate(), OptionError);
  options = {};
  options.old_after_s = 0.0;
  EXPECT_THROW(options.validate(), OptionError);
}

}  // namespace
}  // namespace superdyna::mapping

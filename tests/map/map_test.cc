#include "superdyna/map/map.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <iostream>
#include <latch>
#include <random>
#include <set>
#include <stdexcept>
#include <thread>

#include "superdyna/core/error.h"
#include "superdyna/map/atlas.h"

namespace superdyna::map {
namespace {

KeyFrame makeKeyFrame(int num_keypoints, const SE3d& T_w_b = SE3d()) {
  KeyFrame keyframe;
  keyframe.T_w_b = T_w_b;
  keyframe.keypoints.resize(static_cast<std::size_t>(num_keypoints));
  keyframe.descriptors = cv::Mat::zeros(num_keypoints, 32, CV_8UC1);
  return keyframe;
}

MapPoint makePoint(const Eigen::Vector3d& p_w) {
  MapPoint point;
  point.p_w = p_w;
  return point;
}

/// Three keyframes of 10 keypoints and 10 points: kf0 sees p0..p5, kf1 p3..p8, kf2 p5..p9, each
/// point at keypoint index = point id. Shared: (0,1) p3 p4 p5 = 3, (0,2) p5 = 1, (1,2) p5..p8 = 4.
class ThreeKeyFrameMap : public ::testing::Test {
 protected:
  void SetUp() override {
    for (int k = 0; k < 3; ++k)
      kf[k] = map.addKeyFrame(makeKeyFrame(10));
    for (int i = 0; i < 10; ++i)
      p[i] = map.addMapPoint(makePoint(Eigen::Vector3d(i, 0, 5)));
    observe(kf[0], 0, 5);
    observe(kf[1], 3, 8);
    observe(kf[2], 5, 9);
  }

  void observe(KeyFrameId keyframe, int first, int last) {
    for (int i = first; i <= last; ++i)
      ASSERT_TRUE(map.addObservation(p[i], keyframe, i));
  }

  Map map;
  KeyFrameId kf[3] = {};
  MapPointId p[10] = {};
};

TEST(Map, CountsPointsObservedByKeypointsOfDifferentClasses) {
  Map map;
  KeyFrame labelled = makeKeyFrame(3);
  labelled.keypoints[1].class_id = 1;  // a vehicle
  labelled.keypoints[2].class_id = 1;
  const KeyFrameId a = map.addKeyFrame(makeKeyFrame(3));  // all background
  const KeyFrameId b = map.addKeyFrame(std::move(labelled));
  MapPointId p[3];
  for (int i = 0; i < 3; ++i)
    p[i] = map.addMapPoint(makePoint(Eigen::Vector3d(i, 0, 5)));
  map.addObservation(p[0], a, 0);  // background in both
  map.addObservation(p[0], b, 0);
  map.addObservation(p[1], a, 1);  // background and vehicle
  map.addObservation(p[1], b, 1);
  map.addObservation(p[2], b, 2);  // a vehicle seen once
  EXPECT_EQ(map.numCrossClassMapPoints(), 1u);
  map.setMapPointBad(p[1]);
  EXPECT_EQ(map.numCrossClassMapPoints(), 0u);
}

TEST_F(ThreeKeyFrameMap, ObservationsAreMirroredAndWeightsCountSharedPoints) {
  EXPECT_EQ(map.consistencyError(), "");
  const KeyFrame kf1 = *map.keyFrame(kf[1]);
  EXPECT_EQ(kf1.numTrackedPoints(), 6);
  EXPECT_EQ(kf1.map_points[3], p[3]);
  EXPECT_EQ(kf1.map_points[2], kNoMapPoint);
  const MapPoint p5 = *map.mapPoint(p[5]);
  EXPECT_EQ(p5.numObservations(), 3);
  EXPECT_EQ(p5.observations.at(kf[2]), 5);

  EXPECT_EQ(map.covisibilityWeight(kf[0], kf[1]), 3);
  EXPECT_EQ(map.covisibilityWeight(kf[1], kf[0]), 3);
  EXPECT_EQ(map.covisibilityWeight(kf[0], kf[2]), 1);
  EXPECT_EQ(map.covisibilityWeight(kf[1], kf[2]), 4);
  EXPECT_EQ(map.covisibleKeyFrames(kf[1]),
            (std::vector<CovisibleKeyFrame>{{kf[2], 4}, {kf[0], 3}}));
  EXPECT_EQ(map.bestCovisibleKeyFrames(kf[0], 1), (std::vector<KeyFrameId>{kf[1]}));
  EXPECT_EQ(map.covisibleKeyFrames(kf[0], 2), (std::vector<CovisibleKeyFrame>{{kf[1], 3}}));
}

TEST_F(ThreeKeyFrameMap, ErasingObservationsLowersWeightsAndDropsEmptyEdges) {
  ASSERT_TRUE(map.eraseObservation(p[5], kf[0]));
  EXPECT_FALSE(map.eraseObservation(p[5], kf[0]));  // already gone
  EXPECT_EQ(map.keyFrame(kf[0])->map_points[5], kNoMapPoint);
  EXPECT_FALSE(map.mapPoint(p[5])->observations.contains(kf[0]));
  EXPECT_EQ(map.covisibilityWeight(kf[0], kf[1]), 2);
  EXPECT_EQ(map.covisibilityWeight(kf[0], kf[2]), 0);
  EXPECT_EQ(map.covisibleKeyFrames(kf[2]), (std::vector<CovisibleKeyFrame>{{kf[1], 4}}));
  EXPECT_EQ(map.covisibilityWeight(kf[1], kf[2]), 4);
  EXPECT_EQ(map.consistencyError(), "");
}

TEST_F(ThreeKeyFrameMap, ErasingAKeyFrameRemovesItsObservationsAndEdges) {
  const auto orphans = map.eraseKeyFrame(kf[1]);
  ASSERT_TRUE(orphans.has_value());
  EXPECT_TRUE(orphans->empty());  // p3..p8 are all seen by kf0 or kf2 as well
  EXPECT_FALSE(map.hasKeyFrame(kf[1]));
  for (int i = 3; i <= 8; ++i)
    EXPECT_FALSE(map.mapPoint(p[i])->observations.contains(kf[1]));
  EXPECT_EQ(map.mapPoint(p[6])->numObservations(), 1);
  EXPECT_EQ(map.covisibilityWeight(kf[0], kf[2]), 1);
  EXPECT_EQ(map.covisibleKeyFrames(kf[0]), (std::vector<CovisibleKeyFrame>{{kf[2], 1}}));
  EXPECT_EQ(map.consistencyError(), "");

  const auto orphans_of_kf2 = map.eraseKeyFrame(kf[2]);
  EXPECT_EQ(*orphans_of_kf2, (std::vector<MapPointId>{p[6], p[7], p[8], p[9]}));
  EXPECT_TRUE(map.covisibleKeyFrames(kf[0]).empty());
  EXPECT_FALSE(map.eraseKeyFrame(kf[2]).has_value());
  EXPECT_EQ(map.consistencyError(), "");
}

TEST_F(ThreeKeyFrameMap, ErasingAPointRemovesItFromEveryKeyFrame) {
  ASSERT_TRUE(map.eraseMapPoint(p[5]));
  EXPECT_FALSE(map.hasMapPoint(p[5]));
  for (int k = 0; k < 3; ++k)
    EXPECT_EQ(map.keyFrame(kf[k])->map_points[5], kNoMapPoint);
  EXPECT_EQ(map.covisibilityWeight(kf[0], kf[1]), 2);
  EXPECT_EQ(map.covisibilityWeight(kf[0], kf[2]), 0);
  EXPECT_EQ(map.covisibilityWeight(kf[1], kf[2]), 3);
  EXPECT_EQ(map.consistencyError(), "");
}

TEST_F(ThreeKeyFrameMap, ObservationReplacesTheOldPointAtAKeypointAndMovesIndices) {
  // p9 now observed by keypoint 3 of kf0: replaces p3 there (p3 was shared with kf1).
  ASSERT_TRUE(map.addObservation(p[9], kf[0], 3));
  EXPECT_EQ(map.keyFrame(kf[0])->map_points[3], p[9]);
  EXPECT_FALSE(map.mapPoint(p[3])->observations.contains(kf[0]));
  EXPECT_EQ(map.covisibilityWeight(kf[0], kf[1]), 2);  // p4, p5
  EXPECT_EQ(map.covisibilityWeight(kf[0], kf[2]), 2);  // p5, p9
  // Moving p9 to keypoint 7 of kf0 frees keypoint 3 and keeps the weights.
  ASSERT_TRUE(map.addObservation(p[9], kf[0], 7));
  EXPECT_EQ(map.keyFrame(kf[0])->map_points[3], kNoMapPoint);
  EXPECT_EQ(map.mapPoint(p[9])->observations.at(kf[0]), 7);
  EXPECT_EQ(map.covisibilityWeight(kf[0], kf[2]), 2);
  EXPECT_EQ(map.consistencyError(), "");

  EXPECT_FALSE(map.addObservation(p[0], kf[0], 10));  // index out of range
  EXPECT_FALSE(map.addObservation(p[0], 99, 0));      // unknown keyframe
  EXPECT_FALSE(map.addObservation(99, kf[0], 0));     // unknown point
}

TEST_F(ThreeKeyFrameMap, ReplacingAPointMergesObservationsAndCounters) {
  ASSERT_TRUE(map.increaseVisible(p[0], 4));  // visible 5, found 1
  ASSERT_TRUE(map.increaseFound(p[9], 2));    // visible 1, found 3
  // p0 (kf0 only) fused into p9 (kf2): kf0 keeps keypoint 0, now observing p9.
  ASSERT_TRUE(map.replaceMapPoint(p[0], p[9]));
  EXPECT_FALSE(map.hasMapPoint(p[0]));
  const MapPoint p9 = *map.mapPoint(p[9]);
  EXPECT_EQ(p9.observations, (std::map<KeyFrameId, int>{{kf[0], 0}, {kf[2], 9}}));
  EXPECT_EQ(p9.visible_count, 6);
  EXPECT_EQ(p9.found_count, 4);
  EXPECT_DOUBLE_EQ(p9.foundRatio(), 4.0 / 6.0);
  EXPECT_EQ(map.covisibilityWeight(kf[0], kf[2]), 2);
  // p3 fused into p4 (both seen by kf0 and kf1): the duplicate keypoints lose their point.
  ASSERT_TRUE(map.replaceMapPoint(p[3], p[4]));
  EXPECT_EQ(map.keyFrame(kf[0])->map_points[3], kNoMapPoint);
  EXPECT_EQ(map.covisibilityWeight(kf[0], kf[1]), 2);
  EXPECT_FALSE(map.replaceMapPoint(p[4], p[4]));
  EXPECT_EQ(map.consistencyError(), "");
}

TEST_F(ThreeKeyFrameMap, BadPointsLoseObservationsAndAreErasedLater) {
  ASSERT_TRUE(map.setMapPointBad(p[5]));
  EXPECT_TRUE(map.hasMapPoint(p[5]));
  EXPECT_TRUE(map.mapPoint(p[5])->bad);
  EXPECT_EQ(map.mapPoint(p[5])->numObservations(), 0);
  EXPECT_EQ(map.covisibilityWeight(kf[0], kf[2]), 0);
  EXPECT_FALSE(map.addObservation(p[5], kf[0], 5));
  EXPECT_EQ(map.mapPointIds().size(), 9u);
  EXPECT_EQ(map.consistencyError(), "");
  EXPECT_EQ(map.eraseBadMapPoints(), 1);
  EXPECT_FALSE(map.hasMapPoint(p[5]));
  EXPECT_EQ(map.numMapPoints(), 9u);
}

TEST(MapTest, AddingAKeyFrameWithAssociationsCreatesObservations) {
  Map map;
  const MapPointId a = map.addMapPoint(makePoint({0, 0, 1}));
  const MapPointId b = map.addMapPoint(makePoint({0, 0, 2}));
  const KeyFrameId first = map.addKeyFrame(makeKeyFrame(4));
  ASSERT_TRUE(map.addObservation(a, first, 0));
  ASSERT_TRUE(map.addObservation(b, first, 1));
  ASSERT_TRUE(map.eraseMapPoint(b));

  KeyFrame second = makeKeyFrame(4);
  second.map_points = {kNoMapPoint, a, b, 12345};  // b was erased, 12345 never existed
  const KeyFrameId id = map.addKeyFrame(second);
  const KeyFrame stored = *map.keyFrame(id);
  EXPECT_EQ(stored.map_points, (std::vector<MapPointId>{kNoMapPoint, a, kNoMapPoint, kNoMapPoint}));
  EXPECT_EQ(map.mapPoint(a)->observations.at(id), 1);
  EXPECT_EQ(map.covisibilityWeight(first, id), 1);
  EXPECT_EQ(map.consistencyError(), "");
}

TEST(MapTest, RejectsMalformedInputs) {
  Map map;
  KeyFrame keyframe = makeKeyFrame(3);
  keyframe.descriptors = cv::Mat::zeros(2, 32, CV_8UC1);
  EXPECT_THROW(map.addKeyFrame(keyframe), std::invalid_argument);
  keyframe = makeKeyFrame(3);
  keyframe.map_points = {kNoMapPoint};
  EXPECT_THROW(map.addKeyFrame(keyframe), std::invalid_argument);
  keyframe = makeKeyFrame(3);
  keyframe.keypoints[1].camera = 1;  // the default rig has one camera
  EXPECT_THROW(map.addKeyFrame(keyframe), std::invalid_argument);
  MapPoint point;
  point.observations[0] = 0;
  EXPECT_THROW(map.addMapPoint(point), std::invalid_argument);

  MapOptions options;
  options.scale_factor = 1.0;
  EXPECT_THROW(Map{options}, OptionError);
  options = {};
  options.T_b_c.clear();
  EXPECT_THROW(Map{options}, OptionError);
}

TEST(MapTest, TwoMapsCountIdsIndependently) {
  Map first, second;
  EXPECT_EQ(first.addKeyFrame(makeKeyFrame(1)), 0);
  EXPECT_EQ(first.addKeyFrame(makeKeyFrame(1)), 1);
  EXPECT_EQ(second.addKeyFrame(makeKeyFrame(1)), 0);
  EXPECT_EQ(first.addMapPoint(makePoint({0, 0, 1})), 0);
  EXPECT_EQ(second.addMapPoint(makePoint({0, 0, 1})), 0);
  EXPECT_EQ(first.addMapPoint(makePoint({0, 0, 1})), 1);
}

TEST(MapTest, NormalAndDistancesFollowTheObservingCameras) {
  MapOptions options;
  options.T_b_c = {SE3d(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.1, 0, 0))};
  Map map(options);
  // Camera centres at (0.1, 0, 0) and (4.1, 0, 0); the point at (2.1, 0, 2): rays at +-45 deg.
  KeyFrame left = makeKeyFrame(2);
  left.keypoints[1].octave = 2;
  const KeyFrameId a = map.addKeyFrame(left);
  const KeyFrameId b =
      map.addKeyFrame(makeKeyFrame(2, SE3d(Eigen::Matrix3d::Identity(), {4, 0, 0})));
  const MapPointId point = map.addMapPoint(makePoint({2.1, 0, 2}));
  EXPECT_FALSE(map.updateNormalAndDistances(point));  // no observation yet
  ASSERT_TRUE(map.addObservation(point, a, 1));
  ASSERT_TRUE(map.addObservation(point, b, 0));
  ASSERT_TRUE(map.updateNormalAndDistances(point));

  const MapPoint stored = *map.mapPoint(point);
  EXPECT_LT((stored.normal_w - Eigen::Vector3d(0, 0, 1)).norm(), 1e-12);
  const double distance = std::sqrt(8.0);  // from the oldest keyframe a
  EXPECT_NEAR(stored.max_distance_m, distance * 1.2 * 1.2, 1e-12);
  EXPECT_NEAR(stored.min_distance_m, distance * 1.2 * 1.2 / std::pow(1.2, 7), 1e-12);
}

TEST(MapTest, RandomEditsKeepTheCovisibilityGraphEqualToARebuild) {
  Map map;
  std::mt19937 rng(42);
  std::vector<KeyFrameId> keyframes;
  std::vector<MapPointId> points;
  for (int i = 0; i < 8; ++i)
    keyframes.push_back(map.addKeyFrame(makeKeyFrame(30)));
  for (int i = 0; i < 60; ++i)
    points.push_back(map.addMapPoint(makePoint({0, 0, 1})));
  const auto pick = [&rng](const auto& ids) {
    return ids[std::uniform_int_distribution<std::size_t>(0, ids.size() - 1)(rng)];
  };
  std::uniform_int_distribution<int> operation(0, 99);
  std::uniform_int_distribution<int> keypoint(0, 29);
  for (int step = 0; step < 3000; ++step) {
    const int op = operation(rng);
    if (op < 60) {
      map.addObservation(pick(points), pick(keyframes), keypoint(rng));
    } else if (op < 85) {
      map.eraseObservation(pick(points), pick(keyframes));
    } else if (op < 90) {
      map.replaceMapPoint(pick(points), pick(points));
    } else if (op < 94) {
      map.eraseKeyFrame(pick(keyframes));
    } else if (op < 97) {
      map.eraseMapPoint(pick(points));
    } else {
      map.setMapPointBad(pick(points));
    }
    // Refill what was erased so the graph stays busy.
    if (map.numKeyFrames() < 8) keyframes.push_back(map.addKeyFrame(makeKeyFrame(30)));
    if (map.mapPointIds().size() < 60) points.push_back(map.addMapPoint(makePoint({0, 0, 1})));
    ASSERT_EQ(map.consistencyError(), "") << "after step " << step;
  }
  int edges = 0;
  for (KeyFrameId id : map.keyFrameIds())
    edges += static_cast<int>(map.covisibleKeyFrames(id).size());
  EXPECT_GT(edges, 0);
}

TEST(MapTest, ConcurrentObservationChangesStayConsistent) {
  Map map;
  std::vector<KeyFrameId> keyframes;
  std::vector<MapPointId> points;
  for (int i = 0; i < 4; ++i)
    keyframes.push_back(map.addKeyFrame(makeKeyFrame(200)));
  for (int i = 0; i < 200; ++i)
    points.push_back(map.addMapPoint(makePoint({0, 0, 1})));
  // Each thread attaches every point to its own two keyframes (same keypoint index).
  const auto attach = [&](int first_keyframe) {
    for (int i = 0; i < 200; ++i) {
      for (int k = first_keyframe; k < first_keyframe + 2; ++k) {
        map.addObservation(points[static_cast<std::size_t>(i)],
                           keyframes[static_cast<std::size_t>(k)], i);
      }
    }
  };
  std::thread first(attach, 0), second(attach, 2);
  first.join();
  second.join();
  EXPECT_EQ(map.consistencyError(), "");
  for (std::size_t a = 0; a < 4; ++a) {
    for (std::size_t b = a + 1; b < 4; ++b) {
      EXPECT_EQ(map.covisibilityWeight(keyframes[a], keyframes[b]), 200);
    }
  }
}

/// One map update of the test below: moves every keyframe and every point 1 m along x, one call
/// each, all under the update lock. Halfway it lets other threads run, as a preempted writer would.
void shiftEverything(Map& map, const std::vector<KeyFrameId>& keyframes,
                     const std::vector<MapPointId>& points) {
  const Eigen::Vector3d step(1.0, 0.0, 0.0);
  const Map::UpdateLock update = map.updateLock();
  for (const KeyFrameId id : keyframes) {
    SE3d T_w_b = *map.keyFramePose(id);
    T_w_b.t += step;
    map.setKeyFramePose(id, T_w_b);
  }
  std::this_thread::yield();
  for (const MapPointId id : points)
    map.setMapPointPosition(id, *map.mapPointPosition(id) + step);
}

/// How far (x, m) each keyframe and point has moved from its start, read under the read lock.
std::vector<double> shiftsSeen(const Map& map, const std::vector<KeyFrameId>& keyframes,
                               const std::vector<MapPointId>& points) {
  const Map::ReadLock reading = map.readLock();
  std::vector<double> shifts;
  for (std::size_t k = 0; k < keyframes.size(); ++k)
    shifts.push_back(map.keyFramePose(keyframes[k])->t.x() - static_cast<double>(k));
  for (std::size_t i = 0; i < points.size(); ++i)
    shifts.push_back(map.mapPointPosition(points[i])->x() - static_cast<double>(i));
  return shifts;
}

TEST(MapUpdate, AReaderUnderTheReadLockSeesEachUpdateEntirelyOrNotAtAll) {
  constexpr int kUpdates = 200;
  constexpr int kMaxReads = 1000000;  // bound; the reader stops when the writer is done
  Map map;
  std::vector<KeyFrameId> keyframes;
  std::vector<MapPointId> points;
  for (int k = 0; k < 10; ++k) {
    keyframes.push_back(map.addKeyFrame(
        makeKeyFrame(1, SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(k, 0.0, 0.0)))));
  }
  for (int i = 0; i < 100; ++i)
    points.push_back(map.addMapPoint(makePoint(Eigen::Vector3d(i, 1.0, 5.0))));

  std::latch start(2);
  std::atomic<bool> done{false};
  std::atomic<int> reads{0};
  std::thread writer([&] {
    start.arrive_and_wait();
    for (int u = 0; u < kUpdates; ++u) {
      const int reads_before = reads;
      shiftEverything(map, keyframes, points);
      // Interleave: the next update waits for a snapshot taken after this one began.
      while (reads == reads_before && reads < kMaxReads)
        std::this_thread::yield();
    }
    done = true;
  });
  start.arrive_and_wait();
  int torn = 0;  // snapshots mixing moved and unmoved parts
  std::set<double> states_seen;
  while (!done && reads < kMaxReads) {
    const std::vector<double> shifts = shiftsSeen(map, keyframes, points);
    ++reads;
    const auto [low, high] = std::minmax_element(shifts.begin(), shifts.end());
    if (*low != *high) {
      ++torn;
    } else {
      states_seen.insert(*low);
    }
  }
  writer.join();
  std::cout << reads << " snapshots during " << kUpdates << " updates: " << states_seen.size()
            << " distinct whole states, " << torn << " torn\n";
  EXPECT_EQ(torn, 0);
  for (const double shift : shiftsSeen(map, keyframes, points))
    ASSERT_EQ(shift, static_cast<double>(kUpdates));
}

}  // namespace
}  // namespace superdyna::map

namespace superdyna::map {
namespace {

TEST_F(ThreeKeyFrameMap, KeyFramesFormATemporalChainThatSurvivesErasing) {
  EXPECT_EQ(map.keyFrame(kf[0])->previous, kNoKeyFrame);
  EXPECT_EQ(map.keyFrame(kf[1])->previous, kf[0]);
  EXPECT_EQ(map.keyFrame(kf[2])->previous, kf[1]);
  EXPECT_EQ(map.newestKeyFrame(), kf[2]);
  EXPECT_EQ(map.nextKeyFrame(kf[0]), kf[1]);
  ASSERT_TRUE(map.eraseKeyFrame(kf[1]));
  EXPECT_EQ(map.keyFrame(kf[2])->previous, kf[0]);
  EXPECT_EQ(map.nextKeyFrame(kf[0]), kf[2]);
  ASSERT_TRUE(map.eraseKeyFrame(kf[2]));
  EXPECT_EQ(map.newestKeyFrame(), kf[0]);
  EXPECT_EQ(map.nextKeyFrame(kf[0]), kNoKeyFrame);
}

TEST(MapTest, MergedImuSamplesDropTheSharedBracketingSample) {
  const auto at = [](TimeNs t) {
    sensors::ImuSample s;
    s.t_ns = t;
    s.gyro.setZero();
    s.accel.setZero();
    return s;
  };
  const std::vector<sensors::ImuSample> merged =
      mergeImuSamples({at(0), at(5), at(10)}, {at(5), at(10), at(15)});
  ASSERT_EQ(merged.size(), 4u);
  EXPECT_EQ(merged.back().t_ns, 15);
}

/// 200 Hz samples of smooth signals over [t0_s, t1_s].
std::vector<sensors::ImuSample> smoothImuRun(double t0_s, double t1_s) {
  std::vector<sensors::ImuSample> samples;
  for (TimeNs t = secondsToNs(t0_s); t <= secondsToNs(t1_s); t += secondsToNs(0.005)) {
    const double s = nsToSeconds(t);
    sensors::ImuSample sample;
    sample.t_ns = t;
    sample.gyro = Eigen::Vector3d(0.1 * std::sin(0.5 * s), 0.2, 0.05 * std::cos(0.2 * s));
    sample.accel = Eigen::Vector3d(0.01 * s, 9.81, std::cos(0.3 * s));
    samples.push_back(sample);
  }
  return samples;
}

/// Integrals of both signals over the samples' span, linear between samples (the way
/// preintegration interpolates them).
std::pair<Eigen::Vector3d, Eigen::Vector3d> trapezoidIntegrals(
    const std::vector<sensors::ImuSample>& samples) {
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();
  for (std::size_t k = 1; k < samples.size(); ++k) {
    const double dt = nsToSeconds(samples[k].t_ns - samples[k - 1].t_ns);
    gyro += 0.5 * dt * (samples[k].gyro + samples[k - 1].gyro);
    accel += 0.5 * dt * (samples[k].accel + samples[k - 1].accel);
  }
  return {gyro, accel};
}

TEST(MapTest, ThinnedImuSamplesKeepTheEndsAndTheIntegrals) {
  const std::vector<sensors::ImuSample> full = smoothImuRun(0.0, 60.0);  // 12 001 samples
  const std::vector<sensors::ImuSample> thinned = thinImuSamples(full, 256);
  ASSERT_EQ(thinned.size(), 256u);
  EXPECT_EQ(thinned.front().t_ns, full.front().t_ns);
  EXPECT_EQ(thinned.back().t_ns, full.back().t_ns);
  EXPECT_EQ(thinned.back().accel, full.back().accel);
  for (std::size_t k = 1; k < thinned.size(); ++k)
    ASSERT_GT(thinned[k].t_ns, thinned[k - 1].t_ns) << "sample " << k;
  const auto [gyro_full, accel_full] = trapezoidIntegrals(full);
  const auto [gyro_thin, accel_thin] = trapezoidIntegrals(thinned);
  // 0.23 s bins of signals that change over seconds: the integrals agree to a few 1e-4.
  EXPECT_LT((gyro_thin - gyro_full).norm(), 1e-3 * gyro_full.norm());
  EXPECT_LT((accel_thin - accel_full).norm(), 1e-4 * accel_full.norm());
  EXPECT_EQ(thinImuSamples(full, full.size()).size(), full.size());  // short enough: unchanged
}

/// Keyframes every 2 s over 60 s, each with its 200 Hz samples; culling every other one 29 times
/// would leave one keyframe linked by all 12 000 samples to the first.
TEST(MapTest, ErasedKeyFramesLeaveTheirSuccessorsAtMostTheLinkSampleLimit) {
  MapOptions options;
  options.max_imu_samples_per_link = 512;
  Map map(options);
  std::vector<KeyFrameId> ids;
  for (int k = 0; k <= 30; ++k) {
    KeyFrame keyframe = makeKeyFrame(1);
    keyframe.t_ns = secondsToNs(2.0 * k);
    if (k > 0) keyframe.imu_from_previous = smoothImuRun(2.0 * (k - 1), 2.0 * k);
    ids.push_back(map.addKeyFrame(std::move(keyframe)));
  }
  for (int k = 1; k < 30; ++k)
    ASSERT_TRUE(map.eraseKeyFrame(ids[static_cast<std::size_t>(k)]));
  const auto last = map.keyFrame(ids.back());  // a copy
  ASSERT_TRUE(last);
  EXPECT_EQ(last->previous, ids.front());
  EXPECT_LE(last->imu_from_previous.size(), 512u);
  EXPECT_EQ(last->imu_from_previous.front().t_ns, 0);
  EXPECT_EQ(last->imu_from_previous.back().t_ns, secondsToNs(60.0));
  const auto [gyro_full, accel_full] = trapezoidIntegrals(smoothImuRun(0.0, 60.0));
  const auto [gyro_kept, accel_kept] = trapezoidIntegrals(last->imu_from_previous);
  EXPECT_LT((gyro_kept - gyro_full).norm(), 1e-3 * gyro_full.norm());
  EXPECT_LT((accel_kept - accel_full).norm(), 1e-4 * accel_full.norm());
}

/// Keyframes at 0, 1 and 2 s with 100 Hz samples between them; the third one's run restarted
/// after an IMU gap from 1.0 to 1.6 s, so it starts at 1.6 s (after its predecessor).
TEST(MapTest, ErasingTheKeyFrameBeforeAnImuGapLeavesTheSuccessorUnlinked) {
  const auto run = [](double t0_s, double t1_s) {
    std::vector<sensors::ImuSample> samples;
    for (TimeNs t = secondsToNs(t0_s); t <= secondsToNs(t1_s); t += secondsToNs(0.01)) {
      sensors::ImuSample s;
      s.t_ns = t;
      samples.push_back(s);
    }
    return samples;
  };
  Map map;
  KeyFrameId ids[3] = {};
  for (int k = 0; k < 3; ++k) {
    KeyFrame keyframe = makeKeyFrame(1);
    keyframe.t_ns = secondsToNs(k);
    if (k == 1) keyframe.imu_from_previous = run(0.0, 1.0);
    if (k == 2) keyframe.imu_from_previous = run(1.6, 2.0);
    ids[k] = map.addKeyFrame(std::move(keyframe));
  }
  ASSERT_TRUE(map.eraseKeyFrame(ids[1]));
  EXPECT_EQ(map.keyFrame(ids[2])->previous, ids[0]);
  // Merged, the run would bracket [0, 2] s with one interpolated 0.6 s step over the gap.
  EXPECT_TRUE(map.keyFrame(ids[2])->imu_from_previous.empty());
}

TEST_F(ThreeKeyFrameMap, TransformWorldMovesPosesPointsAndVelocities) {
  ASSERT_TRUE(map.setKeyFrameInertialState(kf[1], Eigen::Vector3d(1, 0, 0), Eigen::Vector3d::Zero(),
                                           Eigen::Vector3d::Zero()));
  ASSERT_TRUE(map.updateNormalAndDistances(p[3]));
  const double max_before = map.mapPoint(p[3])->max_distance_m;
  Sim3d T;
  T.s = 2.0;
  T.R = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.t = Eigen::Vector3d(0, 0, 1);
  map.transformWorld(T);
  EXPECT_TRUE(map.mapPointPosition(p[3])->isApprox(Eigen::Vector3d(0, 6, 11)));
  EXPECT_TRUE(map.keyFrame(kf[1])->v_w.isApprox(Eigen::Vector3d(0, 2, 0)));
  EXPECT_TRUE(map.keyFramePose(kf[1])->t.isApprox(Eigen::Vector3d(0, 0, 1)));
  EXPECT_DOUBLE_EQ(map.mapPoint(p[3])->max_distance_m, 2.0 * max_before);
  EXPECT_EQ(map.consistencyError(), "");
}

TEST_F(ThreeKeyFrameMap, AnEstimatedInertialStateIsMarkedAndARotatedVelocityKeepsTheMark) {
  // The tracker predicts from estimated velocities only (Tracker::predictionStart): a keyframe's
  // state is its insertion-time prediction until an estimation sets it.
  EXPECT_FALSE(map.keyFrame(kf[1])->inertial_estimated);
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  ASSERT_TRUE(map.rotateKeyFrameVelocity(kf[1], R));  // a loop correction
  EXPECT_FALSE(map.keyFrame(kf[1])->inertial_estimated);
  ASSERT_TRUE(map.setKeyFrameInertialState(kf[1], Eigen::Vector3d(1, 0, 0), Eigen::Vector3d::Zero(),
                                           Eigen::Vector3d::Zero()));
  EXPECT_TRUE(map.keyFrame(kf[1])->inertial_estimated);
  EXPECT_FALSE(map.keyFrame(kf[2])->inertial_estimated);
  ASSERT_TRUE(map.rotateKeyFrameVelocity(kf[1], R));
  EXPECT_TRUE(map.keyFrame(kf[1])->inertial_estimated);
  EXPECT_TRUE(map.keyFrame(kf[1])->v_w.isApprox(Eigen::Vector3d(0, 1, 0)));
  EXPECT_FALSE(map.rotateKeyFrameVelocity(KeyFrameId{999}, R));
}

/// A keyframe of one keypoint whose descriptor is `descriptor`.
KeyFrame keyFrameWithDescriptor(const cv::Mat& descriptor) {
  KeyFrame kf;
  kf.keypoints.resize(1);
  kf.descriptors = descriptor.clone();
  return kf;
}

TEST(MapDescriptor, RepresentativeFloatDescriptorHasTheSmallestMedianDistance) {
  Map map;
  // Five one-float observations: 0, 10, 1.9, 2 and 2.1. Median distances (self included, lower
  // median as ORB-SLAM): 2 for 0, 7.9 for 10, 0.2 for 1.9, 0.1 for 2, 0.2 for 2.1: 2 wins.
  const MapPointId point = map.addMapPoint(MapPoint{});
  for (const float value : {0.0f, 10.0f, 1.9f, 2.0f, 2.1f}) {
    const KeyFrameId kf = map.addKeyFrame(keyFrameWithDescriptor(cv::Mat(1, 1, CV_32FC1, value)));
    ASSERT_TRUE(map.addObservation(point, kf, 0));
  }
  ASSERT_TRUE(map.updateDescriptor(point));
  const cv::Mat descriptor = map.mapPoint(point)->descriptor;
  ASSERT_EQ(descriptor.type(), CV_32FC1);
  EXPECT_EQ(descriptor.at<float>(0, 0), 2.0f);
}

TEST(MapDescriptor, RepresentativeBinaryDescriptorUsesHammingDistance) {
  Map map;
  // 0x0F is one bit from 0x0E, 0x0D and 0x0B, which are two bits apart: Hamming median
  // distances 1 (0x0F), 2 (the others) and 4 (0x80), so 0x0F wins; by value (L2) 0x0E would.
  const MapPointId point = map.addMapPoint(MapPoint{});
  for (const int value : {0x80, 0x0E, 0x0F, 0x0D, 0x0B}) {
    const KeyFrameId kf =
        map.addKeyFrame(keyFrameWithDescriptor(cv::Mat(1, 1, CV_8UC1, cv::Scalar(value))));
    ASSERT_TRUE(map.addObservation(point, kf, 0));
  }
  ASSERT_TRUE(map.updateDescriptor(point));
  EXPECT_EQ(map.mapPoint(point)->descriptor.at<std::uint8_t>(0, 0), 0x0F);
  EXPECT_FALSE(map.updateDescriptor(point + 1));
}

TEST(MapOptions, ASinglePyramidLevelAcceptsScaleOne) {
  MapOptions options;
  options.num_levels = 1;
  options.scale_factor = 1.0;
  Map map(options);
  const KeyFrameId kf = map.addKeyFrame(makeKeyFrame(1));
  const MapPointId point = map.addMapPoint(makePoint(Eigen::Vector3d(0.0, 0.0, 4.0)));
  ASSERT_TRUE(map.addObservation(point, kf, 0));
  ASSERT_TRUE(map.updateNormalAndDistances(point));
  EXPECT_NEAR(map.mapPoint(point)->max_distance_m, 4.0, 1e-12);
  EXPECT_NEAR(map.mapPoint(point)->min_distance_m, 4.0, 1e-12);
  options.num_levels = 8;
  EXPECT_THROW(Map{options}, OptionError);
}

TEST(ViewingLimits, AngleAndScaleRangeAsOrbSlam) {
  MapPoint point;
  point.p_w = Eigen::Vector3d(0.0, 0.0, 10.0);
  point.normal_w = Eigen::Vector3d(0.0, 0.0, 1.0);  // seen from below
  point.min_distance_m = 4.0;
  point.max_distance_m = 12.0;
  EXPECT_TRUE(withinViewingLimits(point, Eigen::Vector3d(0.0, 0.0, 0.0)));
  // 59 and 61 degrees off the mean viewing direction, 8 m away.
  const auto at_angle = [&](double deg) {
    const double a = deg * M_PI / 180.0;
    return Eigen::Vector3d(point.p_w - 8.0 * Eigen::Vector3d(std::sin(a), 0.0, std::cos(a)));
  };
  EXPECT_TRUE(withinViewingLimits(point, at_angle(59.0)));
  EXPECT_FALSE(withinViewingLimits(point, at_angle(61.0)));
  // Distance range [0.8 * 4, 1.2 * 12] m along the normal.
  EXPECT_TRUE(withinViewingLimits(point, Eigen::Vector3d(0.0, 0.0, 10.0 - 3.3)));
  EXPECT_FALSE(withinViewingLimits(point, Eigen::Vector3d(0.0, 0.0, 10.0 - 3.1)));
  EXPECT_TRUE(withinViewingLimits(point, Eigen::Vector3d(0.0, 0.0, 10.0 - 14.3)));
  EXPECT_FALSE(withinViewingLimits(point, Eigen::Vector3d(0.0, 0.0, 10.0 - 14.5)));
}

TEST(ViewingLimits, SingleScalePointsAndPointsWithoutNormalAreNotBounded) {
  MapPoint point;
  point.p_w = Eigen::Vector3d(0.0, 0.0, 10.0);
  point.normal_w = Eigen::Vector3d(0.0, 0.0, 1.0);
  point.min_distance_m = point.max_distance_m = 10.0;  // one pyramid level
  EXPECT_TRUE(withinViewingLimits(point, Eigen::Vector3d(0.0, 0.0, -20.0)));
  EXPECT_TRUE(withinViewingLimits(point, Eigen::Vector3d(0.0, 0.0, 9.0)));
  point.normal_w.setZero();  // not computed yet
  EXPECT_TRUE(withinViewingLimits(point, Eigen::Vector3d(0.0, 0.0, 20.0)));
  EXPECT_FALSE(withinViewingLimits(point, point.p_w));  // at the camera centre
}

}  // namespace
}  // namespace superdyna::map

namespace superdyna::map {
namespace {

SE3d poseAt(double yaw_rad, const Eigen::Vector3d& t) {
  return SE3d(Eigen::Quaterniond(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ())), t);
}

bool samePose(const SE3d& a, const SE3d& b) {
  return a.t.isApprox(b.t, 1e-12) && a.q.angularDistance(b.q) < 1e-12;
}

// kf1 shares 3 points with kf0 and 4 with kf2: erased, it follows kf2 (its best covisible one).
TEST_F(ThreeKeyFrameMap, AnErasedKeyFrameFollowsTheLaterCorrectionsOfItsAnchor) {
  ASSERT_TRUE(map.setKeyFramePose(kf[1], poseAt(0.1, {1, 0, 0})));
  ASSERT_TRUE(map.setKeyFramePose(kf[2], poseAt(0.2, {2, 0, 0})));
  const SE3d T_2_1 = map.keyFramePose(kf[2])->inverse() * *map.keyFramePose(kf[1]);
  ASSERT_TRUE(map.eraseKeyFrame(kf[1]));
  EXPECT_FALSE(map.keyFramePose(kf[1]));
  // Correct kf2: the erased keyframe moves with it; kf0 moving does not move it.
  const SE3d corrected = poseAt(0.3, {2.5, -1, 0.2});
  ASSERT_TRUE(map.setKeyFramePose(kf[2], corrected));
  ASSERT_TRUE(map.setKeyFramePose(kf[0], poseAt(-0.4, {9, 9, 9})));
  EXPECT_TRUE(samePose(*map.resolvedKeyFramePose(kf[1]), corrected * T_2_1));
  EXPECT_TRUE(samePose(*map.resolvedKeyFramePose(kf[2]), corrected));
  EXPECT_FALSE(map.resolvedKeyFramePose(42));
}

TEST_F(ThreeKeyFrameMap, ErasedKeyFramesResolveThroughAChainOfAnchors) {
  ASSERT_TRUE(map.setKeyFramePose(kf[1], poseAt(0.1, {1, 0, 0})));
  ASSERT_TRUE(map.setKeyFramePose(kf[2], poseAt(0.2, {2, 0, 0})));
  const SE3d T_w_1 = *map.keyFramePose(kf[1]);
  const SE3d T_w_2 = *map.keyFramePose(kf[2]);
  ASSERT_TRUE(map.eraseKeyFrame(kf[1]));  // anchored to kf2
  ASSERT_TRUE(map.eraseKeyFrame(kf[2]));  // anchored to kf0 (shares p5), the last one left
  const SE3d moved = poseAt(0.5, {0, 3, 0});
  ASSERT_TRUE(map.setKeyFramePose(kf[0], moved));
  EXPECT_TRUE(samePose(*map.resolvedKeyFramePose(kf[2]), moved * T_w_2));
  EXPECT_TRUE(samePose(*map.resolvedKeyFramePose(kf[1]), moved * T_w_1));
}

// The anchor relation is kept between cameras: a change of the world with scale (the monocular
// inertial initialisation) moves an erased keyframe exactly as it moves a living one.
TEST(MapTest, AnErasedKeyFrameFollowsAScaledChangeOfTheWorld) {
  MapOptions options;
  options.T_b_c = {poseAt(0.3, {0.05, -0.02, 0.01})};
  Map map(options);
  const SE3d T_w_a = poseAt(0.1, {1, 2, 0});
  const SE3d T_w_e = poseAt(-0.2, {1.5, 2.2, 0.1});
  const KeyFrameId anchor = map.addKeyFrame(makeKeyFrame(1, T_w_a));
  const KeyFrameId erased = map.addKeyFrame(makeKeyFrame(1, T_w_e));
  const MapPointId shared = map.addMapPoint(makePoint({0, 0, 5}));
  ASSERT_TRUE(map.addObservation(shared, anchor, 0));
  ASSERT_TRUE(map.addObservation(shared, erased, 0));
  ASSERT_TRUE(map.eraseKeyFrame(erased));
  Sim3d S;
  S.s = 2.5;
  S.R = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitX()).toRotationMatrix();
  S.t = Eigen::Vector3d(0.3, 0, -1);
  map.transformWorld(S);
  const SE3d& T_b_c = options.T_b_c.front();
  const SE3d expected = (S * (T_w_e * T_b_c)) * T_b_c.inverse();
  const SE3d resolved = *map.resolvedKeyFramePose(erased);
  EXPECT_LT((resolved.t - expected.t).norm(), 1e-12);
  EXPECT_LT(resolved.q.angularDistance(expected.q), 1e-12);
}

TEST(MapCorrections, ASimilarityMovesPosesAndPointsAndComposes) {
  const SE3d C(Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ())),
               Eigen::Vector3d(1, 2, 3));
  const KeyFrameCorrection first{0, C, 2.0};
  const SE3d T(Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX())),
               Eigen::Vector3d(0.5, -1, 4));
  const Eigen::Vector3d p(0.3, 0.2, 0.1);
  // The pose moves as the point at its position; its rotation turns by C.
  EXPECT_LT((first.apply(T).t - first.apply(T.t)).norm(), 1e-12);
  EXPECT_LT((first.apply(p) - (2.0 * (C.rotation() * p) + C.t)).norm(), 1e-12);
  EXPECT_LT(first.apply(T).q.angularDistance(C.q * T.q), 1e-12);
  // A point fixed in the body frame stays fixed in it, at the scaled distance.
  const Eigen::Vector3d in_body(0.0, 0.0, 1.0);
  EXPECT_NEAR((first.apply(T * in_body) - first.apply(T).t).norm(), 2.0, 1e-12);
  const KeyFrameCorrection second{0, T, 0.5};
  const KeyFrameCorrection both = second.after(first);
  EXPECT_EQ(both.scale, 1.0);
  EXPECT_LT((both.apply(p) - second.apply(first.apply(p))).norm(), 1e-12);
  // Scale 1 is exactly SE3d's product.
  const KeyFrameCorrection rigid{0, C, 1.0};
  EXPECT_EQ(rigid.apply(T).t, (C * T).t);
  EXPECT_EQ(rigid.apply(T).q.coeffs(), (C * T).q.coeffs());
}

TEST(MapCorrections, AreLoggedAndLookedUpByTime) {
  Map map;
  EXPECT_EQ(map.correctionCount(), 0);
  EXPECT_TRUE(map.correctionsSince(0).empty());
  MapCorrection correction;
  const SE3d a(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0));
  const SE3d b(Eigen::Quaterniond::Identity(), Eigen::Vector3d(2, 0, 0));
  correction.keyframes = {{100, a, 1.0}, {200, b, 1.0}};
  EXPECT_EQ(correction.correctionAt(50).C.t.x(), 1.0);   // before all: the first
  EXPECT_EQ(correction.correctionAt(150).C.t.x(), 1.0);  // the keyframe before
  EXPECT_EQ(correction.correctionAt(200).C.t.x(), 2.0);
  EXPECT_EQ(correction.correctionAt(900).C.t.x(), 2.0);
  EXPECT_EQ(MapCorrection{}.correctionAt(5).C.t.norm(), 0.0);
  EXPECT_EQ(MapCorrection{}.correctionAt(5).scale, 1.0);
  map.recordCorrection(correction);
  map.recordCorrection(MapCorrection{});
  EXPECT_EQ(map.correctionCount(), 2);
  EXPECT_EQ(map.correctionsSince(0).size(), 2u);
  ASSERT_EQ(map.correctionsSince(1).size(), 1u);
  EXPECT_TRUE(map.correctionsSince(1).front().keyframes.empty());
  EXPECT_TRUE(map.correctionsSince(2).empty());
}

TEST(PredictedOctave, RoundsTheScaleRatioUpWithinThePyramid) {
  MapPoint point;
  point.max_distance_m = 12.0;  // seen at octave 0 from 12 m
  EXPECT_EQ(predictedOctave(point, 20.0, 1.2, 8), 0) << "farther than the range: finest";
  EXPECT_EQ(predictedOctave(point, 11.0, 1.2, 8), 1);  // log(12/11)/log(1.2) = 0.48
  EXPECT_EQ(predictedOctave(point, 5.0, 1.2, 8), 5);   // 4.80
  EXPECT_EQ(predictedOctave(point, 1.0, 1.2, 8), 7) << "13.6, clamped to the coarsest";
  EXPECT_EQ(predictedOctave(point, 5.0, 1.2, 1), 0) << "single-scale extractor";
  point.max_distance_m = 0.0;
  EXPECT_EQ(predictedOctave(point, 5.0, 1.2, 8), 0) << "no range yet";
}

}  // namespace
}  // namespace superdyna::map

namespace superdyna::map {
namespace {

TEST(MapMerge, AMapContinuingAnotherCountsOnFromItsNextIds) {
  Map first;
  first.addKeyFrame(makeKeyFrame(1));
  first.addKeyFrame(makeKeyFrame(1));
  first.addMapPoint(makePoint({0, 0, 1}));
  Map second(MapOptions{}, first.nextKeyFrameId(), first.nextMapPointId());
  EXPECT_EQ(second.addKeyFrame(makeKeyFrame(1)), 2);
  EXPECT_EQ(second.addMapPoint(makePoint({0, 0, 1})), 1);
  EXPECT_EQ(second.keyFrame(2)->previous, kNoKeyFrame);  // a map's first keyframe
  EXPECT_THROW(Map(MapOptions{}, -1, 0), std::invalid_argument);
}

TEST_F(ThreeKeyFrameMap, AbsorbingAnOlderMapKeepsBothGraphsAndTheNewestKeyFrame) {
  // `map` (ids kf 0-2, points 0-9) is the older map; the active one continues its ids.
  const SE3d T_w_b(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())),
                   Eigen::Vector3d(1, 2, 3));
  ASSERT_TRUE(map.eraseKeyFrame(kf[0]).has_value());  // anchored to kf1: its pose must come along
  const SE3d T_w_0 = *map.resolvedKeyFramePose(kf[0]);
  Map active(MapOptions{}, map.nextKeyFrameId(), map.nextMapPointId());
  const KeyFrameId a = active.addKeyFrame(makeKeyFrame(4, T_w_b));
  const KeyFrameId b = active.addKeyFrame(makeKeyFrame(4, T_w_b));
  const MapPointId q = active.addMapPoint(makePoint({0, 0, 7}));
  ASSERT_TRUE(active.addObservation(q, a, 0));
  ASSERT_TRUE(active.addObservation(q, b, 1));
  const std::size_t old_points = map.numMapPoints();

  active.absorb(map);
  EXPECT_EQ(map.numKeyFrames(), 0u);
  EXPECT_EQ(map.numMapPoints(), 0u);
  EXPECT_EQ(active.keyFrameIds(), (std::vector<KeyFrameId>{kf[1], kf[2], a, b}));
  EXPECT_EQ(active.numMapPoints(), old_points + 1);
  EXPECT_EQ(active.newestKeyFrame(), b);
  EXPECT_EQ(active.keyFrame(kf[2])->previous, kf[1]);  // both temporal chains stay as they were
  EXPECT_EQ(active.keyFrame(a)->previous, kNoKeyFrame);
  EXPECT_EQ(active.covisibilityWeight(kf[1], kf[2]), 4);
  EXPECT_EQ(active.covisibilityWeight(a, b), 1);
  EXPECT_EQ(active.covisibilityWeight(a, kf[1]), 0);
  EXPECT_TRUE(samePose(*active.resolvedKeyFramePose(kf[0]), T_w_0));
  EXPECT_EQ(active.consistencyError(), "");
  // New elements continue after both maps' ids; a fused point links the two graphs.
  EXPECT_EQ(active.addKeyFrame(makeKeyFrame(10)), b + 1);
  EXPECT_EQ(active.keyFrame(b + 1)->previous, b);
  ASSERT_TRUE(active.addObservation(p[6], b + 1, 6));
  ASSERT_TRUE(active.addObservation(q, kf[1], 0));
  EXPECT_EQ(active.covisibilityWeight(kf[1], b + 1), 1);
  EXPECT_EQ(active.consistencyError(), "");
}

TEST(Atlas, KeepsTheMapsLeftAndHandsEachOutOnce) {
  Atlas atlas;
  auto first = std::make_shared<Map>();
  first->addKeyFrame(makeKeyFrame(1));
  first->addKeyFrame(makeKeyFrame(1));
  auto second = std::make_shared<Map>(MapOptions{}, first->nextKeyFrameId(), 0);
  second->addKeyFrame(makeKeyFrame(1));
  atlas.add(first);
  atlas.add(std::make_shared<Map>());  // an empty map is not kept
  atlas.add(second);
  EXPECT_EQ(atlas.numMaps(), 2u);
  EXPECT_EQ(atlas.numKeyFrames(), 3u);
  EXPECT_EQ(atlas.keyFrameIds(), (std::vector<KeyFrameId>{0, 1, 2}));
  EXPECT_EQ(atlas.mapOf(1), first);
  EXPECT_EQ(atlas.mapOf(2), second);
  EXPECT_EQ(atlas.mapOf(3), nullptr);
  EXPECT_EQ(atlas.take(first.get()), first);
  EXPECT_EQ(atlas.take(first.get()), nullptr);  // taken already: a second merge of it fails
  EXPECT_EQ(atlas.mapOf(0), nullptr);
  EXPECT_EQ(atlas.keyFrameIds(), (std::vector<KeyFrameId>{2}));
  atlas.clear();
  EXPECT_EQ(atlas.numMaps(), 0u);
}

TEST_F(ThreeKeyFrameMap, AbsorbRefusesMapsSharingAnIdAndChangesNeither) {
  Map clash;  // counts from 0 as `map` did
  clash.addKeyFrame(makeKeyFrame(1));
  EXPECT_THROW(map.absorb(clash), std::invalid_argument);
  EXPECT_EQ(map.numKeyFrames(), 3u);
  EXPECT_EQ(clash.numKeyFrames(), 1u);
  EXPECT_THROW(map.absorb(map), std::invalid_argument);
  MapOptions stereo;
  stereo.T_b_c = {SE3d(), SE3d()};
  Map rig(stereo, 100, 100);
  EXPECT_THROW(map.absorb(rig), std::invalid_argument);
}

}  // namespace
}  // namespace superdyna::map

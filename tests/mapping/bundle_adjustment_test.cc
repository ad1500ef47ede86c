#include "superdyna/mapping/bundle_adjustment.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <latch>
#include <map>
#include <optional>
#include <thread>
#include <vector>

#include "mapping/mapping_test_scene.h"

namespace superdyna::mapping {
namespace {

struct WindowErrors {
  double position_m = 0.0;  ///< Largest position error in the window.
  double rotation_deg = 0.0;
  double velocity = 0.0;  ///< Largest velocity error [m/s].
};

WindowErrors windowErrors(const test::MappingScene& scene, std::size_t first) {
  WindowErrors e;
  for (std::size_t k = first; k < scene.ids.size(); ++k) {
    const map::KeyFrame kf = *scene.map->keyFrame(scene.ids[k]);
    const test::TruthState& truth = scene.truth[k];
    e.position_m = std::max(e.position_m, (kf.T_w_b.t - truth.T_w_b.t).norm());
    e.rotation_deg =
        std::max(e.rotation_deg, kf.T_w_b.q.angularDistance(truth.T_w_b.q) * 180.0 / M_PI);
    e.velocity = std::max(e.velocity, (kf.v_w - truth.v_w).norm());
  }
  return e;
}

/// Truth everywhere; then the newest `window` keyframes get pose, velocity and bias errors.
test::MappingScene perturbedScene(std::size_t window) {
  test::SceneOptions options;
  test::MappingScene scene = test::makeMappingScene(options);
  for (std::size_t k = 0; k < scene.ids.size(); ++k) {
    const test::TruthState& truth = scene.truth[k];
    scene.map->setKeyFrameInertialState(scene.ids[k], truth.v_w, truth.bias.bg, truth.bias.ba);
  }
  for (std::size_t k = scene.ids.size() - window; k < scene.ids.size(); ++k) {
    const double sign = k % 2 == 0 ? 1.0 : -1.0;
    const SE3d error(expSO3(Eigen::Vector3d(0.008, -0.006, 0.01) * sign),
                     Eigen::Vector3d(0.03, -0.02, 0.025) * sign);
    scene.map->setKeyFramePose(scene.ids[k], scene.truth[k].T_w_b * error);
    scene.map->setKeyFrameInertialState(scene.ids[k],
                                        scene.truth[k].v_w + Eigen::Vector3d(0.15, -0.1, 0.05),
                                        Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  }
  return scene;
}

TEST(BundleAdjustmentTest, InertialLocalBaRemovesInjectedErrors) {
  constexpr std::size_t kWindow = 6;
  test::MappingScene scene = perturbedScene(kWindow);
  const std::size_t first = scene.ids.size() - kWindow;
  const WindowErrors before = windowErrors(scene, first);
  EXPECT_GT(before.position_m, 0.03);
  EXPECT_GT(before.velocity, 0.15);

  BundleAdjustmentWindow window;
  window.inertial = true;
  window.optimised.assign(scene.ids.begin() + static_cast<std::ptrdiff_t>(first), scene.ids.end());
  window.fixed = {scene.ids[first - 1]};
  KeyFramePreintegrations preintegrations(scene.noise);
  BundleAdjustmentSettings settings;
  settings.iterations = 20;
  const BundleAdjustmentResult result =
      bundleAdjust(*scene.map, window, {scene.camera}, {}, settings,
                   BundleAdjustmentImu{SE3d(), &preintegrations});
  EXPECT_EQ(result.imu_edges, static_cast<int>(kWindow));
  EXPECT_GT(result.observations, 200);
  EXPECT_EQ(result.outliers, 0);

  const WindowErrors after = windowErrors(scene, first);
  EXPECT_LT(after.position_m, 0.002);
  EXPECT_LT(after.rotation_deg, 0.05);
  // Vision cannot see velocities: only the IMU factors bring them back.
  EXPECT_LT(after.velocity, 0.02);
  const map::KeyFrame newest = *scene.map->keyFrame(scene.ids.back());
  EXPECT_LT((newest.bg - scene.truth.back().bias.bg).norm(), 0.01);
  EXPECT_EQ(scene.map->consistencyError(), "");
}

/// Keyframes 50 ms apart at their true states, except the window's anchor (the keyframe before
/// it), whose velocity is 10 % short: a stale estimate of an earlier window. Returns the window's
/// largest position error after the VI local BA.
double positionErrorAfterStaleAnchorVelocity(bool free_anchor_velocity) {
  constexpr std::size_t kWindow = 8;
  test::SceneOptions options;
  options.keyframes = 14;
  options.spacing_s = 0.05;
  test::MappingScene scene = test::makeMappingScene(options);
  for (std::size_t k = 0; k < scene.ids.size(); ++k) {
    const test::TruthState& truth = scene.truth[k];
    scene.map->setKeyFrameInertialState(scene.ids[k], truth.v_w, truth.bias.bg, truth.bias.ba);
  }
  const std::size_t first = scene.ids.size() - kWindow;
  const test::TruthState& anchor = scene.truth[first - 1];
  scene.map->setKeyFrameInertialState(scene.ids[first - 1], 0.9 * anchor.v_w, anchor.bias.bg,
                                      anchor.bias.ba);
  BundleAdjustmentWindow window;
  window.inertial = true;
  window.free_anchor_velocity_below_s = free_anchor_velocity ? 0.2 : 0.0;
  window.optimised.assign(scene.ids.begin() + static_cast<std::ptrdiff_t>(first), scene.ids.end());
  window.fixed = {scene.ids[first - 1]};
  KeyFramePreintegrations preintegrations(scene.noise);
  BundleAdjustmentSettings settings;
  settings.iterations = 20;
  bundleAdjust(*scene.map, window, {scene.camera}, {}, settings,
               BundleAdjustmentImu{SE3d(), &preintegrations});
  EXPECT_EQ(scene.map->keyFrame(scene.ids[first - 1])->v_w, 0.9 * anchor.v_w);  // not written
  return windowErrors(scene, first).position_m;
}

TEST(BundleAdjustmentTest, AStaleAnchorVelocityHeldMovesDenseKeyFramesAFreeOneDoesNot) {
  const double held = positionErrorAfterStaleAnchorVelocity(false);
  const double free = positionErrorAfterStaleAnchorVelocity(true);
  EXPECT_GT(held, 0.01);    // 4.8 cm
  EXPECT_LT(free, 0.0005);  // 3 um
}

TEST(BundleAdjustmentTest, VisualBaLeavesVelocitiesAlone) {
  constexpr std::size_t kWindow = 6;
  test::MappingScene scene = perturbedScene(kWindow);
  const std::size_t first = scene.ids.size() - kWindow;
  BundleAdjustmentWindow window;
  window.optimised.assign(scene.ids.begin() + static_cast<std::ptrdiff_t>(first), scene.ids.end());
  window.fixed = {scene.ids[first - 1]};
  const BundleAdjustmentResult result =
      bundleAdjust(*scene.map, window, {scene.camera}, {}, BundleAdjustmentSettings{});
  EXPECT_EQ(result.imu_edges, 0);
  const WindowErrors after = windowErrors(scene, first);
  EXPECT_LT(after.position_m, 0.002);
  EXPECT_NEAR(after.velocity, std::sqrt(0.15 * 0.15 + 0.1 * 0.1 + 0.05 * 0.05), 1e-12);
}

/// Moves a point observed by `keyframe` along the viewing ray of another observer until it is
/// behind `keyframe` (by 5 cm or more) and at least 5 cm in front of two or more other observers,
/// then erases its observations by every keyframe it is neither behind nor in front of that way:
/// the point ends up observed by `keyframe`, which it is behind, and by keyframes it is in front
/// of (at the map's current poses). Returns the point's id.
map::MapPointId placeBehind(test::MappingScene& scene, map::KeyFrameId keyframe) {
  const auto depth = [&](map::KeyFrameId id, const Eigen::Vector3d& p_w) {
    return (scene.map->keyFramePose(id)->inverse() * p_w).z();
  };
  for (const map::MapPointId id : scene.point_ids) {
    const map::MapPoint point = *scene.map->mapPoint(id);
    if (!point.observations.contains(keyframe)) continue;
    for (const auto& [ray_kf, index] : point.observations) {
      const Eigen::Vector3d centre = scene.map->keyFramePose(ray_kf)->t;
      for (double s = 0.01; s < 1.0; s += 0.01) {
        const Eigen::Vector3d p_w = centre + s * (point.p_w - centre);
        if (depth(keyframe, p_w) > -0.05) continue;
        std::vector<map::KeyFrameId> elsewhere;
        for (const auto& [observer, keypoint] : point.observations) {
          if (observer != keyframe && depth(observer, p_w) < 0.05) elsewhere.push_back(observer);
        }
        if (point.observations.size() - elsewhere.size() < 3) continue;
        for (const map::KeyFrameId observer : elsewhere)
          scene.map->eraseObservation(id, observer);
        scene.map->setMapPointPosition(id, p_w);
        scene.map->updateNormalAndDistances(id);
        return id;
      }
    }
  }
  return map::kNoMapPoint;
}

TEST(BundleAdjustmentTest, APointBehindOneKeyFrameDoesNotStopTheBaAndLosesThatObservation) {
  // Ceres abandons the whole solve when a residual cannot be evaluated at the initial state, so
  // this one observation used to leave every keyframe of the window where it was.
  constexpr std::size_t kWindow = 6;
  test::MappingScene scene = perturbedScene(kWindow);
  const std::size_t first = scene.ids.size() - kWindow;
  const map::KeyFrameId behind_kf = scene.ids.back();  // several others are behind it
  const map::MapPointId behind_point = placeBehind(scene, behind_kf);
  ASSERT_NE(behind_point, map::kNoMapPoint);
  const WindowErrors before = windowErrors(scene, first);
  EXPECT_GT(before.position_m, 0.03);
  EXPECT_GT(before.rotation_deg, 0.5);

  BundleAdjustmentWindow window;
  window.optimised.assign(scene.ids.begin() + static_cast<std::ptrdiff_t>(first), scene.ids.end());
  window.fixed = {scene.ids[first - 1]};
  const BundleAdjustmentResult result =
      bundleAdjust(*scene.map, window, {scene.camera}, {}, BundleAdjustmentSettings{});
  const WindowErrors after = windowErrors(scene, first);
  std::printf(
      "point behind keyframe %d: window error %.1f mm / %.3f deg -> %.2f mm / %.4f deg, "
      "%d residuals, %d outliers removed\n",
      static_cast<int>(behind_kf), 1e3 * before.position_m, before.rotation_deg,
      1e3 * after.position_m, after.rotation_deg, result.observations, result.outliers);
  EXPECT_LT(after.position_m, 0.002);
  EXPECT_LT(after.rotation_deg, 0.05);
  EXPECT_EQ(result.outliers, 1);  // only the observation from behind
  const map::KeyFrame kf = *scene.map->keyFrame(behind_kf);
  EXPECT_EQ(std::count(kf.map_points.begin(), kf.map_points.end(), behind_point), 0);
  // Its observers in front keep it, and the BA pulls it back where they agree.
  const std::optional<map::MapPoint> point = scene.map->mapPoint(behind_point);
  ASSERT_TRUE(point.has_value());
  EXPECT_FALSE(point->observations.contains(behind_kf));
  EXPECT_GE(point->observations.size(), 2u);
  EXPECT_EQ(scene.map->consistencyError(), "");
}

/// Truth everywhere, except the first keyframe's velocity, biases and roll.
test::MappingScene sceneWithAWrongFirstState() {
  test::MappingScene scene = perturbedScene(0);
  const map::KeyFrameId first = scene.ids.front();
  const test::TruthState& truth = scene.truth.front();
  scene.map->setKeyFrameInertialState(first, truth.v_w + Eigen::Vector3d(0.2, -0.15, 0.1),
                                      truth.bias.bg + Eigen::Vector3d(0.01, -0.01, 0.005),
                                      truth.bias.ba);
  const SE3d tilted(expSO3(Eigen::Vector3d(0.01, 0.0, 0.0)) * truth.T_w_b.rotation(),
                    truth.T_w_b.t);
  scene.map->setKeyFramePose(first, tilted);
  return scene;
}

TEST(BundleAdjustmentTest, FullInertialBaHoldsOnlyTheYawAndPositionOfTheFirstKeyFrame) {
  // The full BA after the inertial initialisation used to freeze the first keyframe's velocity,
  // biases and tilt with its pose: whatever the initialisation got wrong there stayed wrong.
  test::MappingScene scene = sceneWithAWrongFirstState();
  const map::KeyFrameId first = scene.ids.front();
  const SE3d start = *scene.map->keyFramePose(first);
  KeyFramePreintegrations preintegrations(scene.noise);
  BundleAdjustmentSettings settings;
  settings.iterations = 30;
  bundleAdjust(*scene.map, fullInertialWindow(scene.ids, 0.0, 0.0), {scene.camera}, {}, settings,
               BundleAdjustmentImu{SE3d(), &preintegrations});
  const map::KeyFrame kf = *scene.map->keyFrame(first);
  const test::TruthState& truth = scene.truth.front();
  std::printf(
      "first keyframe: velocity error %.4f m/s, gyro bias error %.5f rad/s, tilt %.4f deg\n",
      (kf.v_w - truth.v_w).norm(), (kf.bg - truth.bias.bg).norm(),
      test::tiltDifferenceDeg(kf.T_w_b, truth.T_w_b));
  EXPECT_LT((kf.v_w - truth.v_w).norm(), 0.01);
  EXPECT_LT((kf.bg - truth.bias.bg).norm(), 1e-3);
  EXPECT_LT(test::tiltDifferenceDeg(kf.T_w_b, truth.T_w_b), 0.05);
  // The gauge: the position exactly as it was, and the rotation changed about horizontal world
  // axes only (up to the second-order term of composing the tilt updates).
  EXPECT_EQ(kf.T_w_b.t, start.t);
  const Eigen::Vector3d change = logSO3(kf.T_w_b.rotation() * start.rotation().transpose());
  EXPECT_GT(change.head<2>().norm(), 0.009);
  EXPECT_LT(std::abs(change.z()), 1e-4);
}

TEST(BundleAdjustmentTest, TheFullBaBiasPriorIsZeroMeanNotTheCurrentEstimate) {
  // A prior centred on the biases the initialisation just estimated counts the initialisation's
  // own (zero-mean) prior twice and anchors the BA to its starting point: two BAs from different
  // starting biases then ended at different biases. With the zero-mean prior they agree.
  const auto optimisedGyroBias = [](const Eigen::Vector3d& start_bg) {
    test::MappingScene scene = perturbedScene(0);
    for (const map::KeyFrameId id : scene.ids) {
      const map::KeyFrame kf = *scene.map->keyFrame(id);
      scene.map->setKeyFrameInertialState(id, kf.v_w, start_bg, kf.ba);
    }
    KeyFramePreintegrations preintegrations(scene.noise);
    BundleAdjustmentSettings settings;
    settings.iterations = 30;
    bundleAdjust(*scene.map, fullInertialWindow(scene.ids, 1e-3, 0.1), {scene.camera}, {}, settings,
                 BundleAdjustmentImu{SE3d(), &preintegrations});
    return scene.map->keyFrame(scene.ids.front())->bg;
  };
  const Eigen::Vector3d a = optimisedGyroBias(Eigen::Vector3d(0.01, 0.0, 0.0));
  const Eigen::Vector3d b = optimisedGyroBias(Eigen::Vector3d(-0.01, 0.005, 0.0));
  std::printf("gyro bias from two starts: (%.5f %.5f %.5f) vs (%.5f %.5f %.5f)\n", a.x(), a.y(),
              a.z(), b.x(), b.y(), b.z());
  EXPECT_LT((a - b).norm(), 1e-4);
}

/// What a BA changes in the map: keyframe poses and inertial states, point positions, normals and
/// distance ranges.
struct MapState {
  struct KeyFrameState {
    SE3d T_w_b;
    Eigen::Vector3d v_w, bg, ba;
  };
  struct PointState {
    Eigen::Vector3d p_w, normal_w;
    double min_distance_m = 0.0;
    double max_distance_m = 0.0;
  };
  std::map<map::KeyFrameId, KeyFrameState> keyframes;
  std::map<map::MapPointId, PointState> points;
};

/// Bit for bit.
bool sameState(const MapState& a, const MapState& b) {
  const auto same_keyframe = [](const auto& x, const auto& y) {
    return x.first == y.first && x.second.T_w_b.q.coeffs() == y.second.T_w_b.q.coeffs() &&
           x.second.T_w_b.t == y.second.T_w_b.t && x.second.v_w == y.second.v_w &&
           x.second.bg == y.second.bg && x.second.ba == y.second.ba;
  };
  const auto same_point = [](const auto& x, const auto& y) {
    return x.first == y.first && x.second.p_w == y.second.p_w &&
           x.second.normal_w == y.second.normal_w &&
           x.second.min_distance_m == y.second.min_distance_m &&
           x.second.max_distance_m == y.second.max_distance_m;
  };
  return std::equal(a.keyframes.begin(), a.keyframes.end(), b.keyframes.begin(), b.keyframes.end(),
                    same_keyframe) &&
         std::equal(a.points.begin(), a.points.end(), b.points.begin(), b.points.end(), same_point);
}

/// The map's state, read under its read lock.
MapState stateOf(const map::Map& map) {
  const map::Map::ReadLock reading = map.readLock();
  MapState state;
  for (const map::KeyFrameId id : map.keyFrameIds()) {
    map.readKeyFrame(id, [&](const map::KeyFrame& kf) {
      state.keyframes[id] = {kf.T_w_b, kf.v_w, kf.bg, kf.ba};
    });
  }
  for (const map::MapPointId id : map.mapPointIds()) {
    map.readMapPoint(id, [&](const map::MapPoint& p) {
      state.points[id] = {p.p_w, p.normal_w, p.min_distance_m, p.max_distance_m};
    });
  }
  return state;
}

/// Puts poses, inertial states and points back as in `state` (normals and distances recomputed),
/// as one map update.
void restore(map::Map& map, const MapState& state) {
  const map::Map::UpdateLock update = map.updateLock();
  for (const auto& [id, kf] : state.keyframes) {
    map.setKeyFramePose(id, kf.T_w_b);
    map.setKeyFrameInertialState(id, kf.v_w, kf.bg, kf.ba);
  }
  for (const auto& [id, point] : state.points) {
    map.setMapPointPosition(id, point.p_w);
    map.updateNormalAndDistances(id);
  }
}

TEST(BundleAdjustmentTest, AReaderUnderTheReadLockSeesTheMapBeforeOrAfterTheBaNeverBetween) {
  // The local BA runs in the mapping thread while the tracker reads the map: its write-back and
  // outlier removal (hundreds of calls) must reach a reader under the map's read lock as one
  // update. Each round restores the same start, so every BA writes the same result.
  constexpr std::size_t kWindow = 6;
  constexpr int kRounds = 100;
  constexpr int kMaxReads = 1000000;  // bound; the reader stops when the writer is done
  test::MappingScene scene = perturbedScene(kWindow);
  map::Map& map = *scene.map;
  const std::size_t first = scene.ids.size() - kWindow;
  BundleAdjustmentWindow window;
  window.inertial = true;
  window.optimised.assign(scene.ids.begin() + static_cast<std::ptrdiff_t>(first), scene.ids.end());
  window.fixed = {scene.ids[first - 1]};
  BundleAdjustmentSettings settings;
  settings.iterations = 2;
  const auto run_ba = [&] {
    KeyFramePreintegrations preintegrations(scene.noise);  // fresh: the same result every round
    return bundleAdjust(map, window, {scene.camera}, {}, settings,
                        BundleAdjustmentImu{SE3d(), &preintegrations});
  };
  const MapState start_state = stateOf(map);
  restore(map, start_state);
  const MapState before = stateOf(map);
  ASSERT_EQ(run_ba().outliers, 0);  // the map's observations stay the same from round to round
  const MapState after = stateOf(map);
  ASSERT_FALSE(sameState(before, after));
  restore(map, start_state);
  ASSERT_TRUE(sameState(stateOf(map), before));

  std::latch go(2);
  std::atomic<bool> done{false};
  std::thread mapping([&] {
    go.arrive_and_wait();
    for (int round = 0; round < kRounds; ++round) {
      restore(map, start_state);
      run_ba();
    }
    done = true;
  });
  go.arrive_and_wait();
  int reads = 0;
  int seen_before = 0;
  int seen_after = 0;
  int torn = 0;
  while (!done && reads < kMaxReads) {
    const MapState seen = stateOf(map);
    ++reads;
    if (sameState(seen, before)) {
      ++seen_before;
    } else if (sameState(seen, after)) {
      ++seen_after;
    } else {
      ++torn;
    }
  }
  mapping.join();
  std::printf("%d snapshots during %d BAs: %d before, %d after, %d torn\n", reads, kRounds,
              seen_before, seen_after, torn);
  EXPECT_EQ(torn, 0);
  EXPECT_TRUE(sameState(stateOf(map), after));
}

TEST(BundleAdjustmentTest, ASolutionAppliedLaterCarriesItsChangeToTheKeyFramesMadeMeanwhile) {
  // A global BA solved away from the map (DeferredBundleAdjustment): keyframes 2-9 are solved,
  // 10 and 11 stand for keyframes the tracker added after the state was loaded. Every keyframe
  // from 2 on starts 1-2 cm off the truth; keyframe 11 moves once more after loading (a local BA
  // meanwhile). Applied, the solved keyframes take the solution, 10 and 11 move with keyframe 9's
  // correction (the solution relative to its pose at apply), velocities rotated with it, and the
  // corrections are recorded for the poses held outside the map.
  test::MappingScene scene = test::makeMappingScene({});
  const std::vector<map::KeyFrameId>& ids = scene.ids;
  for (std::size_t k = 2; k < ids.size(); ++k) {
    const double angle = static_cast<double>(k);
    const SE3d error(expSO3(Eigen::Vector3d(0.0, 0.0, 0.002 * std::sin(angle))),
                     0.01 * Eigen::Vector3d(std::cos(angle), std::sin(angle), 0.5));
    scene.map->setKeyFramePose(ids[k], error * scene.truth[k].T_w_b);
    scene.map->setKeyFrameInertialState(ids[k], Eigen::Vector3d(1.0, 0.5, -0.2),
                                        Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  }
  BundleAdjustmentWindow window;
  window.fixed = {ids[0], ids[1]};  // a monocular map's gauge: position and scale
  window.optimised.assign(ids.begin() + 2, ids.begin() + 10);
  BundleAdjustmentSettings settings;
  settings.iterations = 20;
  const int generation = scene.map->correctionCount();
  DeferredBundleAdjustment ba(*scene.map, window, {scene.camera}, {}, settings);
  EXPECT_EQ(ba.generation(), generation);
  const SE3d meanwhile(expSO3(Eigen::Vector3d(0.0, 0.001, 0.0)), Eigen::Vector3d(0.0, 0.003, 0.0));
  scene.map->setKeyFramePose(ids[11], meanwhile * *scene.map->keyFramePose(ids[11]));
  const MapState loaded = stateOf(*scene.map);
  ba.solve();
  EXPECT_TRUE(sameState(stateOf(*scene.map), loaded));  // solving touches no map
  const BundleAdjustmentResult result = ba.apply();
  EXPECT_GT(result.observations, 300);

  double solved_error = 0.0;
  for (std::size_t k = 2; k < 10; ++k) {
    solved_error = std::max(solved_error,
                            (scene.map->keyFramePose(ids[k])->t - scene.truth[k].T_w_b.t).norm());
  }
  EXPECT_LT(solved_error, 0.5e-3);
  const SE3d C = *scene.map->keyFramePose(ids[9]) * loaded.keyframes.at(ids[9]).T_w_b.inverse();
  EXPECT_GT(C.t.norm(), 0.005);  // keyframe 9 did move
  for (const std::size_t k : {std::size_t{10}, std::size_t{11}}) {
    const map::KeyFrame kf = *scene.map->keyFrame(ids[k]);
    const SE3d expected = C * loaded.keyframes.at(ids[k]).T_w_b;
    EXPECT_LT((kf.T_w_b.t - expected.t).norm(), 1e-12) << "keyframe " << k;
    EXPECT_LT(kf.T_w_b.q.angularDistance(expected.q), 1e-12) << "keyframe " << k;
    EXPECT_LT((kf.v_w - C.rotation() * loaded.keyframes.at(ids[k]).v_w).norm(), 1e-12);
  }
  EXPECT_EQ(scene.map->keyFramePose(ids[0])->t, loaded.keyframes.at(ids[0]).T_w_b.t);  // held
  ASSERT_EQ(scene.map->correctionCount(), generation + 1);
  const map::MapCorrection recorded = scene.map->correctionsSince(generation).front();
  const map::KeyFrameCorrection newest = recorded.correctionAt(scene.map->keyFrame(ids[11])->t_ns);
  EXPECT_LT((newest.C.t - C.t).norm(), 1e-12);
  EXPECT_EQ(recorded.keyframes.size(), ids.size());
  EXPECT_EQ(scene.map->consistencyError(), "");
}

TEST(BundleAdjustmentTest, InertialWindowNeedsTheImuContext) {
  test::MappingScene scene = test::makeMappingScene({});
  BundleAdjustmentWindow window;
  window.inertial = true;
  window.optimised = {scene.ids[1]};
  window.fixed = {scene.ids[0]};
  EXPECT_THROW(bundleAdjust(*scene.map, window, {scene.camera}, {}, {}), std::invalid_argument);
}

}  // namespace
}  // namespace superdyna::mapping

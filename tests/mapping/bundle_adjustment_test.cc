#include "superdyna/mapping/bundle_adjustment.h"

#include <gtest/gtest.h>

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

#include "superdyna/mapping/inertial_map_initializer.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "mapping/mapping_test_scene.h"
#include "superdyna/core/error.h"

namespace superdyna::mapping {
namespace {

using test::makeMappingScene;
using test::SceneOptions;

/// A visual frame rotated and shifted against the gravity-aligned world.
SE3d visualFrame() {
  return SE3d(expSO3(Eigen::Vector3d(0.4, -0.7, 1.2)), Eigen::Vector3d(2.0, -1.0, 0.5));
}

InertialMapInitOptions looseBiasPriors() {
  InertialMapInitOptions options;
  options.gyro_bias_prior_sigma = 1.0;
  options.accel_bias_prior_sigma = 1.0;
  return options;
}

TEST(InertialMapInitializerTest, RecoversGravityVelocitiesAndBiasesAtFixedScale) {
  SceneOptions scene_options;
  scene_options.T_v_w = visualFrame();
  test::MappingScene scene = makeMappingScene(scene_options);
  const InertialMapInitResult result =
      initializeInertialMap(*scene.map, SE3d(), scene.noise, looseBiasPriors());
  ASSERT_TRUE(result.applied) << result.reason;
  EXPECT_EQ(result.keyframes, 12);
  EXPECT_NEAR(result.duration_s, 2.75, 1e-9);
  EXPECT_DOUBLE_EQ(result.T_new_old.s, 1.0);
  for (std::size_t k = 0; k < scene.ids.size(); ++k) {
    const map::KeyFrame kf = *scene.map->keyFrame(scene.ids[k]);
    const test::TruthState& truth = scene.truth[k];
    // Gravity as seen from the body agrees; the velocity agrees in the body frame (the new world
    // differs from the true one by a yaw and a shift only).
    EXPECT_LT(test::tiltDifferenceDeg(kf.T_w_b, truth.T_w_b), 0.05) << k;
    const Eigen::Vector3d v_b = kf.T_w_b.q.inverse() * kf.v_w;
    const Eigen::Vector3d v_b_true = truth.T_w_b.q.inverse() * truth.v_w;
    EXPECT_LT((v_b - v_b_true).norm(), 0.01) << k;
    EXPECT_LT((kf.bg - truth.bias.bg).norm(), 1e-3) << k;
    EXPECT_LT((kf.ba - truth.bias.ba).norm(), 0.02) << k;
  }
  // Map points moved with the keyframes: their depth in each camera is unchanged.
  const map::KeyFrame first = *scene.map->keyFrame(scene.ids.front());
  const Eigen::Vector3d p = *scene.map->mapPointPosition(first.map_points.front());
  const Eigen::Vector3d p_c = first.T_w_b.inverse() * p;
  const map::KeyFrameKeypoint& keypoint = first.keypoints.front();
  EXPECT_NEAR(p_c.x() / p_c.z(), keypoint.normalized.x(), 1e-9);
  EXPECT_NEAR(p_c.y() / p_c.z(), keypoint.normalized.y(), 1e-9);
}

TEST(InertialMapInitializerTest, EstimatesTheScaleWhenAsked) {
  SceneOptions scene_options;
  scene_options.T_v_w = visualFrame();
  scene_options.scale = 2.5;  // one visual unit = 2.5 m
  test::MappingScene scene = makeMappingScene(scene_options);
  InertialMapInitOptions options = looseBiasPriors();
  options.estimate_scale = true;
  const InertialMapInitResult result =
      initializeInertialMap(*scene.map, SE3d(), scene.noise, options);
  ASSERT_TRUE(result.applied) << result.reason;
  EXPECT_NEAR(result.T_new_old.s, 2.5, 0.01);
  // The map is metric now: keyframe distances match the truth.
  const SE3d first = *scene.map->keyFramePose(scene.ids.front());
  const SE3d last = *scene.map->keyFramePose(scene.ids.back());
  const double truth = (scene.truth.back().T_w_b.t - scene.truth.front().T_w_b.t).norm();
  EXPECT_NEAR((last.t - first.t).norm(), truth, 0.005 * truth);
  EXPECT_LT(test::tiltDifferenceDeg(last, scene.truth.back().T_w_b), 0.1);
}

TEST(InertialMapInitializerTest, WithoutMotionKeepsTheAccelerometerBiasNearZero) {
  // Excitation guard: too little rotation caps the accelerometer bias prior.
  SceneOptions scene_options;
  scene_options.keyframes = 12;
  test::MappingScene scene = makeMappingScene(scene_options);
  InertialMapInitOptions options = looseBiasPriors();
  options.min_rotation_for_accel_bias_deg = 360.0;  // treat the lively motion as unexcited
  const InertialMapInitResult result =
      initializeInertialMap(*scene.map, SE3d(), scene.noise, options);
  ASSERT_TRUE(result.applied) << result.reason;
  EXPECT_DOUBLE_EQ(result.accel_bias_prior_sigma, options.unexcited_accel_bias_prior_sigma);
  // The true bias (0.077 m/s^2) is pulled well towards zero; the loose prior recovers it.
  EXPECT_LT(result.estimate.bias.ba.norm(), 0.03);
  EXPECT_LT((result.estimate.bias.bg - scene.truth.front().bias.bg).norm(), 2e-3);
}

TEST(InertialMapInitializerTest, RefusesTooFewOrTooShortKeyframes) {
  SceneOptions scene_options;
  scene_options.keyframes = 6;
  test::MappingScene scene = makeMappingScene(scene_options);
  const SE3d before = *scene.map->keyFramePose(scene.ids.back());
  const InertialMapInitResult few = initializeInertialMap(*scene.map, SE3d(), scene.noise);
  EXPECT_FALSE(few.applied);
  EXPECT_NE(few.reason.find("6 linked keyframes, 10 needed"), std::string::npos) << few.reason;
  InertialMapInitOptions options;
  options.min_keyframes = 3;
  options.min_duration_s = 2.0;
  const InertialMapInitResult short_span =
      initializeInertialMap(*scene.map, SE3d(), scene.noise, options);
  EXPECT_FALSE(short_span.applied);
  EXPECT_NE(short_span.reason.find("1.25 s"), std::string::npos) << short_span.reason;
  EXPECT_EQ(scene.map->keyFramePose(scene.ids.back())->t, before.t);
}

/// The excitation a refused scale estimation reports ("acceleration excitation X below ...").
double reportedExcitation(const InertialMapInitResult& result) {
  const std::string prefix = "acceleration excitation ";
  const std::size_t at = result.reason.find(prefix);
  if (at == std::string::npos) return -1.0;
  return std::stod(result.reason.substr(at + prefix.size()));
}

TEST(InertialMapInitializerTest, ScaleExcitationIsMetricWhateverTheVisualScale) {
  // The same motion mapped at visual scales 10x apart: the IMU-measured excitation, and so the
  // decision, is the same (a threshold in visual units would refuse one and accept the other).
  std::vector<double> excitations;
  for (const double scale : {0.5, 5.0}) {
    SceneOptions scene_options;
    scene_options.T_v_w = visualFrame();
    scene_options.scale = scale;
    test::MappingScene scene = makeMappingScene(scene_options);
    InertialMapInitOptions options = looseBiasPriors();
    options.estimate_scale = true;
    options.min_scale_excitation = 100.0;  // m/s^2: far more than any flight
    const InertialMapInitResult refused =
        initializeInertialMap(*scene.map, SE3d(), scene.noise, options);
    EXPECT_FALSE(refused.applied);
    EXPECT_NE(refused.reason.find("below 100.000 m/s^2"), std::string::npos) << refused.reason;
    excitations.push_back(reportedExcitation(refused));
    ASSERT_GT(excitations.back(), 0.1) << refused.reason;  // the lively motion excites the scale
    options.min_scale_excitation = 0.5 * excitations.back();
    const InertialMapInitResult applied =
        initializeInertialMap(*scene.map, SE3d(), scene.noise, options);
    ASSERT_TRUE(applied.applied) << applied.reason;
    EXPECT_NEAR(applied.T_new_old.s, scale, 0.01 * scale);
  }
  EXPECT_NEAR(excitations[0], excitations[1], 1e-3);
}

TEST(InertialMapInitializerTest, RejectsInvalidOptions) {
  map::Map map;
  InertialMapInitOptions options;
  options.min_keyframes = 2;
  EXPECT_THROW(initializeInertialMap(map, SE3d(), imu::ImuNoise{}, options), OptionError);
  options = {};
  options.accel_bias_prior_sigma = 0.0;
  EXPECT_THROW(initializeInertialMap(map, SE3d(), imu::ImuNoise{}, options), OptionError);
}

}  // namespace
}  // namespace superdyna::mapping

#include "superdyna/optim/pose_optimizer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <random>
#include <stdexcept>

#include "superdyna/core/error.h"

namespace superdyna::optim {
namespace {

constexpr double kWidthPx = 640.0;
constexpr double kHeightPx = 480.0;
constexpr double kFocalPx = 450.0;
constexpr double kCxPx = 320.0;
constexpr double kCyPx = 240.0;
constexpr double kDegPerRad = 180.0 / M_PI;

/// Synthetic 2D-3D matches of one frame.
struct Scene {
  SE3d T_w_b_true;
  std::vector<ReprojectionCamera> cameras;
  std::vector<PoseObservation> observations;
  std::vector<bool> is_outlier;
};

struct SceneOptions {
  int num_matches = 200;
  double outlier_fraction = 0.2;
  double noise_px = 1.0;  ///< Gaussian pixel noise per axis (level-0 pixels).
  int max_octave = 0;     ///< Octaves drawn uniformly from [0, max_octave].
  double stereo_fraction = 0.0;
  double second_camera_fraction = 0.0;
};

std::vector<ReprojectionCamera> makeRig() {
  ReprojectionCamera left;  // forward-looking camera mounted like EuRoC's cam0 (rotated, offset)
  left.T_b_c =
      SE3d(expSO3(Eigen::Vector3d(0.02, -0.03, 1.56)), Eigen::Vector3d(-0.02, -0.06, 0.01));
  left.fx = left.fy = kFocalPx;
  left.baseline_m = 0.11;
  ReprojectionCamera side = left;  // a second, unrectified camera looking 30 deg to the side
  side.T_b_c =
      left.T_b_c * SE3d(expSO3(Eigen::Vector3d(0.0, 0.52, 0.0)), Eigen::Vector3d(0.1, 0, 0));
  side.baseline_m = 0.0;
  return {left, side};
}

Scene makeScene(const SceneOptions& options, std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_real_distribution<double> u_px(0.0, kWidthPx), v_px(0.0, kHeightPx);
  std::uniform_real_distribution<double> depth_m(2.0, 20.0), fraction(0.0, 1.0);
  std::uniform_int_distribution<int> octave(0, options.max_octave);
  std::normal_distribution<double> noise(0.0, options.noise_px);
  Scene scene;
  scene.cameras = makeRig();
  scene.T_w_b_true = SE3d(expSO3(Eigen::Vector3d(unit(rng), unit(rng), unit(rng))),
                          Eigen::Vector3d(unit(rng), unit(rng), unit(rng)) * 5.0);
  const int num_outliers =
      static_cast<int>(std::lround(options.outlier_fraction * options.num_matches));
  for (int i = 0; i < options.num_matches; ++i) {
    PoseObservation observation;
    observation.camera = fraction(rng) < options.second_camera_fraction ? 1 : 0;
    const ReprojectionCamera& camera = scene.cameras[static_cast<std::size_t>(observation.camera)];
    const Eigen::Vector2d pixel(u_px(rng), v_px(rng));
    const Eigen::Vector3d p_c = depth_m(rng) * Eigen::Vector3d((pixel.x() - kCxPx) / kFocalPx,
                                                               (pixel.y() - kCyPx) / kFocalPx, 1.0);
    observation.p_w = scene.T_w_b_true * (camera.T_b_c * p_c);
    observation.octave = octave(rng);
    const bool outlier = i < num_outliers;  // the order is irrelevant to the optimiser
    const Eigen::Vector2d observed_px = outlier ? Eigen::Vector2d(u_px(rng), v_px(rng))
                                                : pixel + Eigen::Vector2d(noise(rng), noise(rng));
    observation.normalized = (observed_px - Eigen::Vector2d(kCxPx, kCyPx)) / kFocalPx;
    if (camera.baseline_m > 0.0 && fraction(rng) < options.stereo_fraction) {
      const double right_u = kFocalPx * (p_c.x() - camera.baseline_m) / p_c.z() + kCxPx;
      const double observed_right_u = outlier ? u_px(rng) : right_u + noise(rng);
      observation.right_x = (observed_right_u - kCxPx) / kFocalPx;
    }
    scene.observations.push_back(observation);
    scene.is_outlier.push_back(outlier);
  }
  return scene;
}

/// The truth moved by `translation_m` and rotated by `angle_rad`, in random directions.
SE3d perturb(const SE3d& T, double translation_m, double angle_rad, std::mt19937& rng) {
  std::normal_distribution<double> gaussian;
  const Eigen::Vector3d axis =
      Eigen::Vector3d(gaussian(rng), gaussian(rng), gaussian(rng)).normalized();
  const Eigen::Vector3d direction =
      Eigen::Vector3d(gaussian(rng), gaussian(rng), gaussian(rng)).normalized();
  return SE3d(T.rotation() * expSO3(angle_rad * axis), T.t + translation_m * direction);
}

struct Scores {
  double position_error_m = 0.0;
  double rotation_error_deg = 0.0;
  int correct = 0;           ///< Matches classified as what they are.
  int outliers_flagged = 0;  ///< True outliers classified as outliers.
  int inliers_kept = 0;      ///< True inliers classified as inliers.
  int num_outliers = 0;
  int num_inliers = 0;
};

Scores score(const Scene& scene, const PoseOptimizationResult& result) {
  Scores s;
  s.position_error_m = (result.T_w_b.t - scene.T_w_b_true.t).norm();
  s.rotation_error_deg =
      rotationAngle(scene.T_w_b_true.rotation().transpose() * result.T_w_b.rotation()) * kDegPerRad;
  for (std::size_t i = 0; i < scene.observations.size(); ++i) {
    const bool outlier = scene.is_outlier[i];
    s.num_outliers += outlier ? 1 : 0;
    s.num_inliers += outlier ? 0 : 1;
    s.outliers_flagged += (outlier && !result.inliers[i]) ? 1 : 0;
    s.inliers_kept += (!outlier && result.inliers[i]) ? 1 : 0;
  }
  s.correct = s.outliers_flagged + s.inliers_kept;
  return s;
}

void print(const char* label, const Scores& s) {
  std::printf(
      "%s: |dp| %.2f mm, |dR| %.4f deg, correct %d/%d, outliers flagged %d/%d, inliers kept "
      "%d/%d\n",
      label, 1e3 * s.position_error_m, s.rotation_error_deg, s.correct,
      s.num_inliers + s.num_outliers, s.outliers_flagged, s.num_outliers, s.inliers_kept,
      s.num_inliers);
}

TEST(PoseOptimizerTest, RecoversAPoseFrom200MatchesWith20PercentGrossOutliers) {
  // 1 px noise at octave 0 with the 95 % chi^2 test: about 5 % of the true inliers are rejected by
  // construction, so the classification accuracy is about 0.2 + 0.8 * 0.95 = 96 %.
  const PoseOptimizer optimizer;
  int correct = 0, total = 0;
  for (unsigned seed = 1; seed <= 10; ++seed) {
    std::mt19937 rng(seed);
    const Scene scene = makeScene({}, rng);
    const SE3d T_w_b_initial = perturb(scene.T_w_b_true, 0.05, 2.0 / kDegPerRad, rng);
    const PoseOptimizationResult result =
        optimizer.optimize(T_w_b_initial, scene.cameras, scene.observations);
    const Scores s = score(scene, result);
    print(("seed " + std::to_string(seed)).c_str(), s);
    EXPECT_TRUE(result.success);
    EXPECT_EQ(result.rounds_run, 4);
    EXPECT_LT(s.position_error_m, 0.01) << "seed " << seed;
    EXPECT_LT(s.rotation_error_deg, 0.1) << "seed " << seed;
    EXPECT_EQ(s.outliers_flagged, s.num_outliers) << "seed " << seed;
    EXPECT_GE(s.inliers_kept, 0.9 * s.num_inliers) << "seed " << seed;
    EXPECT_EQ(result.num_inliers,
              static_cast<int>(std::count(result.inliers.begin(), result.inliers.end(), true)));
    correct += s.correct;
    total += s.num_inliers + s.num_outliers;
  }
  const double accuracy = static_cast<double>(correct) / total;
  std::printf("classification accuracy over 10 scenes: %.2f %% (%d/%d)\n", 100.0 * accuracy,
              correct, total);
  EXPECT_GT(accuracy, 0.95);
}

TEST(PoseOptimizerTest, KeypointsOnHigherOctavesGetLargerSigmas) {
  // Same 1 px noise, keypoints spread over octaves 0..3 as an ORB pyramid gives them: their larger
  // sigma (1.2^octave px) rejects fewer true inliers.
  std::mt19937 rng(11);
  SceneOptions options;
  options.max_octave = 3;
  const Scene scene = makeScene(options, rng);
  const PoseOptimizationResult result = PoseOptimizer().optimize(
      perturb(scene.T_w_b_true, 0.05, 2.0 / kDegPerRad, rng), scene.cameras, scene.observations);
  const Scores s = score(scene, result);
  print("octaves 0..3", s);
  EXPECT_LT(s.position_error_m, 0.01);
  EXPECT_LT(s.rotation_error_deg, 0.1);
  EXPECT_EQ(s.outliers_flagged, s.num_outliers);
  EXPECT_GT(s.correct, 0.95 * 200);
}

TEST(PoseOptimizerTest, UsesStereoAndSecondCameraObservations) {
  std::mt19937 rng(21);
  SceneOptions options;
  options.stereo_fraction = 0.6;
  options.second_camera_fraction = 0.3;
  const Scene scene = makeScene(options, rng);
  const int stereo = static_cast<int>(
      std::count_if(scene.observations.begin(), scene.observations.end(),
                    [](const PoseObservation& o) { return o.right_x.has_value(); }));
  ASSERT_GT(stereo, 50);
  const PoseOptimizationResult result = PoseOptimizer().optimize(
      perturb(scene.T_w_b_true, 0.05, 2.0 / kDegPerRad, rng), scene.cameras, scene.observations);
  const Scores s = score(scene, result);
  print("stereo + second camera", s);
  EXPECT_LT(s.position_error_m, 0.01);
  EXPECT_LT(s.rotation_error_deg, 0.1);
  EXPECT_EQ(s.outliers_flagged, s.num_outliers);
  EXPECT_GT(s.correct, 0.95 * 200);
}

TEST(PoseOptimizerTest, ReincludesInliersRejectedInEarlierRounds) {
  std::mt19937 rng(31);
  const Scene scene = makeScene({}, rng);
  const SE3d T_w_b_initial = perturb(scene.T_w_b_true, 0.3, 4.0 / kDegPerRad, rng);
  // At the initial pose nearly every true inlier fails the chi^2 test.
  int rejected_at_start = 0;
  for (std::size_t i = 0; i < scene.observations.size(); ++i) {
    const PoseObservation& o = scene.observations[i];
    const auto r =
        ReprojectionFactor(o.normalized, scene.cameras[0], 1.0).residual(T_w_b_initial, o.p_w);
    if (!scene.is_outlier[i] && (!r || r->squaredNorm() > kChi2Mono95)) ++rejected_at_start;
  }
  // The classification after the first round (the same first round as the full run: the
  // optimiser is deterministic) ...
  PoseOptimizerOptions first_round_only;
  first_round_only.rounds = 1;
  first_round_only.robust_rounds = 1;
  first_round_only.iterations_per_round = 3;
  PoseOptimizerOptions options;
  options.iterations_per_round = 3;
  const PoseOptimizationResult first =
      PoseOptimizer(first_round_only).optimize(T_w_b_initial, scene.cameras, scene.observations);
  const PoseOptimizationResult result =
      PoseOptimizer(options).optimize(T_w_b_initial, scene.cameras, scene.observations);
  // ... rejects true inliers that the later rounds bring back.
  int reincluded = 0;
  for (std::size_t i = 0; i < scene.observations.size(); ++i) {
    reincluded += (!scene.is_outlier[i] && !first.inliers[i] && result.inliers[i]) ? 1 : 0;
  }
  const Scores s = score(scene, result);
  std::printf(
      "true inliers failing the chi2 test: %d/%d at the initial pose, %d/%d after round 1; "
      "re-included later: %d\n",
      rejected_at_start, s.num_inliers, s.num_inliers - score(scene, first).inliers_kept,
      s.num_inliers, reincluded);
  print("from 30 cm / 4 deg, 3 iterations per round", s);
  EXPECT_GT(rejected_at_start, s.num_inliers / 2);
  EXPECT_GT(reincluded, 0);
  EXPECT_GE(s.inliers_kept, 0.9 * s.num_inliers);
  EXPECT_EQ(s.outliers_flagged, s.num_outliers);
  EXPECT_LT(s.position_error_m, 0.01);
  EXPECT_LT(s.rotation_error_deg, 0.1);
}

TEST(PoseOptimizerTest, AMatchBehindTheCameraIsLeftOutAndClassifiedAsAnOutlier) {
  // A residual that cannot be evaluated at the initial pose makes Ceres abandon the whole solve.
  std::mt19937 rng(61);
  SceneOptions options;
  options.outlier_fraction = 0.0;
  Scene scene = makeScene(options, rng);
  const SE3d T_w_b_initial = perturb(scene.T_w_b_true, 0.05, 2.0 / kDegPerRad, rng);
  // Match 0's point mirrored through the camera plane of the initial pose.
  PoseObservation& behind = scene.observations[0];
  const ReprojectionCamera& camera = scene.cameras[static_cast<std::size_t>(behind.camera)];
  const Eigen::Vector3d p_c = worldToCamera(T_w_b_initial, camera.T_b_c, behind.p_w);
  behind.p_w = T_w_b_initial * (camera.T_b_c * Eigen::Vector3d(p_c.x(), p_c.y(), -p_c.z()));
  ASSERT_LT(worldToCamera(T_w_b_initial, camera.T_b_c, behind.p_w).z(), -1.0);

  const PoseOptimizationResult result =
      PoseOptimizer().optimize(T_w_b_initial, scene.cameras, scene.observations);
  const Scores s = score(scene, result);
  print("one match behind the camera", s);
  EXPECT_TRUE(result.success);
  EXPECT_LT(s.position_error_m, 0.01);
  EXPECT_LT(s.rotation_error_deg, 0.1);
  EXPECT_FALSE(result.inliers[0]);
  EXPECT_TRUE(std::isinf(result.chi2[0]));
  EXPECT_GE(s.inliers_kept, 0.9 * s.num_inliers);
}

TEST(PoseOptimizerTest, PriorAloneGivesThePriorAndAStrongPriorDominates) {
  std::mt19937 rng(41);
  const Scene scene = makeScene({}, rng);
  PosePrior prior;
  prior.T_w_b = perturb(scene.T_w_b_true, 0.02, 0.5 / kDegPerRad, rng);
  const SE3d T_w_b_initial = perturb(scene.T_w_b_true, 0.05, 2.0 / kDegPerRad, rng);

  prior.information = Eigen::Matrix<double, 6, 6>::Identity() * 1e4;
  const PoseOptimizationResult alone =
      PoseOptimizer().optimize(T_w_b_initial, scene.cameras, {}, prior);
  EXPECT_LT((alone.T_w_b.t - prior.T_w_b.t).norm(), 1e-6);
  EXPECT_LT(rotationAngle(alone.T_w_b.rotation().transpose() * prior.T_w_b.rotation()), 1e-6);
  EXPECT_FALSE(alone.success);  // no inliers

  prior.information = Eigen::Matrix<double, 6, 6>::Identity() * 1e12;
  const PoseOptimizationResult strong =
      PoseOptimizer().optimize(T_w_b_initial, scene.cameras, scene.observations, prior);
  EXPECT_LT((strong.T_w_b.t - prior.T_w_b.t).norm(), 1e-4);

  prior.information = Eigen::Matrix<double, 6, 6>::Identity() * 1e-6;
  const PoseOptimizationResult weak =
      PoseOptimizer().optimize(T_w_b_initial, scene.cameras, scene.observations, prior);
  const Scores s = score(scene, weak);
  EXPECT_LT(s.position_error_m, 0.01);
  EXPECT_LT(s.rotation_error_deg, 0.1);
}

TEST(PoseOptimizerTest, TooFewMatchesIsNotASuccess) {
  std::mt19937 rng(51);
  SceneOptions options;
  options.num_matches = 6;
  options.outlier_fraction = 0.0;
  const Scene scene = makeScene(options, rng);
  const SE3d T_w_b_initial = perturb(scene.T_w_b_true, 0.01, 0.1 / kDegPerRad, rng);
  const PoseOptimizationResult result =
      PoseOptimizer().optimize(T_w_b_initial, scene.cameras, scene.observations);
  EXPECT_FALSE(result.success);
  EXPECT_EQ(result.rounds_run, 0);
  EXPECT_EQ(result.inliers.size(), 6u);
  EXPECT_LT((result.T_w_b.t - T_w_b_initial.t).norm(), 1e-15);
}

TEST(PoseOptimizerTest, RejectsInvalidInputs) {
  const std::vector<ReprojectionCamera> cameras = makeRig();
  PoseObservation observation;
  observation.p_w = Eigen::Vector3d(0, 0, 5);
  observation.camera = 2;
  EXPECT_THROW(PoseOptimizer().optimize(SE3d(), cameras, {observation}), std::invalid_argument);
  observation.camera = 1;  // no baseline
  observation.right_x = 0.0;
  EXPECT_THROW(PoseOptimizer().optimize(SE3d(), cameras, {observation}), std::invalid_argument);
  PosePrior prior;
  prior.information(0, 0) = -1.0;
  EXPECT_THROW(PoseOptimizer().optimize(SE3d(), cameras, {}, prior), OptionError);

  PoseOptimizerOptions options;
  options.robust_rounds = 5;
  EXPECT_THROW(PoseOptimizer{options}, OptionError);
  options = {};
  options.chi2_mono = 0.0;
  EXPECT_THROW(PoseOptimizer{options}, OptionError);
}

}  // namespace
}  // namespace superdyna::optim

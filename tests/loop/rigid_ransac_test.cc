#include "superdyna/loop/rigid_ransac.h"

#include <gtest/gtest.h>

#include <random>

namespace superdyna::loop {
namespace {

TEST(RigidRansac, RecoversAKnownTransformWithOutliers) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> uniform(-5.0, 5.0);
  std::normal_distribution<double> noise(0.0, 0.005);
  const SE3d T_a_b(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized())),
      Eigen::Vector3d(2.0, -1.0, 0.5));
  std::vector<Eigen::Vector3d> a, b;
  std::vector<bool> truth;
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3d p(uniform(rng), uniform(rng), uniform(rng) + 8.0);
    b.push_back(p);
    const bool outlier = i % 10 < 4;  // 40 % wrong matches
    truth.push_back(!outlier);
    a.push_back(outlier ? Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng))
                        : T_a_b * p + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  }
  const auto is_inlier = [&](const SE3d& T, std::size_t i) {
    return (a[i] - T * b[i]).norm() < 0.03;
  };
  const std::optional<RigidRansacResult> result = ransacRigid(a, b, is_inlier);
  ASSERT_TRUE(result);
  EXPECT_EQ(result->num_inliers, 60);
  EXPECT_EQ(result->inliers, truth);
  EXPECT_LT((result->T_a_b.t - T_a_b.t).norm(), 0.005);
  EXPECT_LT(rotationAngle(result->T_a_b.rotation().transpose() * T_a_b.rotation()), 1e-3);
  // Without enough agreeing matches there is no result.
  RigidRansacOptions strict;
  strict.min_inliers = 61;
  EXPECT_FALSE(ransacRigid(a, b, is_inlier, strict));
}

TEST(RigidRansac, SimilarityRecoversTheScaleThatRigidCannot) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> uniform(-5.0, 5.0);
  const double scale = 1.6;  // a monocular map's scale drift between the two sides
  const SE3d T_a_b(Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ())),
                   Eigen::Vector3d(1.0, 0.5, -0.2));
  std::vector<Eigen::Vector3d> a, b;
  for (int i = 0; i < 80; ++i) {
    const Eigen::Vector3d p(uniform(rng), uniform(rng), uniform(rng) + 8.0);
    b.push_back(p);
    a.push_back(i % 4 == 0 ? Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng))
                           : Eigen::Vector3d(scale * (T_a_b.rotation() * p) + T_a_b.t));
  }
  // The caller's test sees (R, t) only: the direction from the camera of b, which the scale
  // leaves alone (as the loop closer's reprojection test).
  const auto is_inlier = [&](const SE3d& T, std::size_t i) {
    const Eigen::Vector3d in_b = T.inverse() * a[i];
    return (in_b.normalized() - b[i].normalized()).norm() < 1e-3;
  };
  const std::optional<RigidRansacResult> similar = ransacSimilarity(a, b, is_inlier);
  ASSERT_TRUE(similar);
  EXPECT_EQ(similar->num_inliers, 60);
  EXPECT_NEAR(similar->scale, scale, 1e-9);
  EXPECT_LT((similar->T_a_b.t - T_a_b.t).norm(), 1e-9);
  EXPECT_LT(rotationAngle(similar->T_a_b.rotation().transpose() * T_a_b.rotation()), 1e-9);
  const std::optional<Sim3d> fit = fitSimilarity(a, b, similar->inliers);
  ASSERT_TRUE(fit);
  EXPECT_NEAR(fit->s, scale, 1e-9);
  // A rigid fit of the same samples points the wrong way: far fewer agree with it.
  const std::optional<RigidRansacResult> rigid = ransacRigid(a, b, is_inlier);
  EXPECT_TRUE(!rigid || rigid->num_inliers < 30);
}

TEST(RigidRansac, FitRejectsCollinearPoints) {
  std::vector<Eigen::Vector3d> line;
  for (int i = 0; i < 5; ++i)
    line.emplace_back(i, 2.0 * i, 0.0);
  EXPECT_FALSE(fitRigid(line, line));
  line.emplace_back(0.0, 0.0, 1.0);
  const std::optional<SE3d> identity = fitRigid(line, line);
  ASSERT_TRUE(identity);
  EXPECT_LT(identity->t.norm(), 1e-9);
}

}  // namespace
}  // namespace superdyna::loop

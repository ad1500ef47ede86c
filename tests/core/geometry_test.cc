#include "superdyna/core/geometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace superdyna {
namespace {

TEST(GeometryTest, ExpLogRoundTripIncludingSmallAndNearPiAngles) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (double angle : {1e-9, 1e-4, 0.3, 2.0, M_PI - 1e-6}) {
    for (int i = 0; i < 10; ++i) {
      const Eigen::Vector3d axis = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
      const Eigen::Vector3d omega = angle * axis;
      const Eigen::Vector3d back = logSO3(expSO3(omega));
      EXPECT_LT((back - omega).norm(), 1e-9 * std::max(1.0, angle)) << "angle " << angle;
      EXPECT_NEAR(rotationAngle(expSO3(omega)), angle, 1e-9);
    }
  }
}

TEST(GeometryTest, HatIsCrossProduct) {
  const Eigen::Vector3d a(0.3, -1.2, 2.0), b(-0.7, 0.4, 1.1);
  EXPECT_LT((hat(a) * b - a.cross(b)).norm(), 1e-15);
}

TEST(GeometryTest, SE3ComposeInverseAndMatrixAgree) {
  const SE3d A(expSO3(Eigen::Vector3d(0.1, -0.4, 0.9)), Eigen::Vector3d(1, 2, 3));
  const SE3d B(expSO3(Eigen::Vector3d(-0.5, 0.2, 0.05)), Eigen::Vector3d(-4, 0.5, 2));
  EXPECT_LT(((A * B).matrix() - A.matrix() * B.matrix()).norm(), 1e-12);
  EXPECT_LT(((A * A.inverse()).matrix() - Eigen::Matrix4d::Identity()).norm(), 1e-12);
  const Eigen::Vector3d p(0.5, -0.25, 4.0);
  EXPECT_LT(((A * p) - (A.matrix() * p.homogeneous()).head<3>()).norm(), 1e-12);
  EXPECT_LT((SE3d::fromMatrix(A.matrix()).matrix() - A.matrix()).norm(), 1e-12);
}

TEST(GeometryTest, NearestRotationRepairsSmallPerturbation) {
  const Eigen::Matrix3d R = expSO3(Eigen::Vector3d(0.2, 0.3, -0.1));
  Eigen::Matrix3d M = R;
  M(0, 1) += 1e-7;
  const Eigen::Matrix3d fixed = nearestRotation(M);
  EXPECT_NEAR(fixed.determinant(), 1.0, 1e-12);
  EXPECT_LT((fixed.transpose() * fixed - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_LT((fixed - R).norm(), 1e-7);
}

TEST(GeometryTest, Sim3InverseAndPoseApplication) {
  Sim3d S;
  S.s = 2.5;
  S.R = expSO3(Eigen::Vector3d(0.3, -0.2, 1.0));
  S.t = Eigen::Vector3d(1, -2, 0.5);
  const Eigen::Vector3d p(0.1, 0.2, 0.3);
  EXPECT_LT((S.inverse() * (S * p) - p).norm(), 1e-12);
  const SE3d pose(expSO3(Eigen::Vector3d(0.0, 0.1, 0.0)), p);
  const SE3d moved = S * pose;
  EXPECT_LT((moved.t - S * p).norm(), 1e-12);
  EXPECT_LT((moved.rotation() - S.R * pose.rotation()).norm(), 1e-12);
}

TEST(GeometryTest, Sim3FromARigidTransform) {
  const Eigen::Vector3d p(0.1, 0.2, 0.3);
  // A rigid transform as a similarity of scale 1 acts as the rigid transform.
  const SE3d T(expSO3(Eigen::Vector3d(0.0, 0.1, 0.2)), Eigen::Vector3d(4, 5, 6));
  EXPECT_LT((Sim3d::fromSE3(T) * p - T * p).norm(), 1e-12);
  EXPECT_LT((Sim3d::fromSE3(T, 3.0) * p - (3.0 * (T.rotation() * p) + T.t)).norm(), 1e-12);
}

TEST(GeometryTest, RightJacobianMatchesCentralDifferencesOfExpAndLog) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double h = 1e-6;
  for (double angle : {0.0, 1e-6, 1e-3, 0.5, 2.5}) {
    const Eigen::Vector3d axis = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    const Eigen::Vector3d phi = angle * axis;
    const Eigen::Matrix3d R = expSO3(phi);
    Eigen::Matrix3d J_exp;  // d log(R^T exp(phi + d)) / dd
    Eigen::Matrix3d J_log;  // d log(R exp(d)) / dd
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d d = h * Eigen::Vector3d::Unit(k);
      J_exp.col(k) =
          (logSO3(R.transpose() * expSO3(phi + d)) - logSO3(R.transpose() * expSO3(phi - d))) /
          (2.0 * h);
      J_log.col(k) = (logSO3(R * expSO3(d)) - logSO3(R * expSO3(-d))) / (2.0 * h);
    }
    EXPECT_LT((J_exp - rightJacobianSO3(phi)).norm(), 1e-8) << "angle " << angle;
    EXPECT_LT((J_log - rightJacobianInverseSO3(phi)).norm(), 1e-8) << "angle " << angle;
    EXPECT_LT(
        (rightJacobianSO3(phi) * rightJacobianInverseSO3(phi) - Eigen::Matrix3d::Identity()).norm(),
        1e-12)
        << "angle " << angle;
  }
}

}  // namespace
}  // namespace superdyna

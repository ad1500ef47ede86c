#include "superdyna/optim/reprojection_factor.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <type_traits>

#include "superdyna/core/error.h"
#include "superdyna/optim/imu_factors.h"
#include "superdyna/optim/se3_manifold.h"

namespace superdyna::optim {
namespace {

/// A random pose, a random camera extrinsic and a point in front of the camera.
struct Configuration {
  SE3d T_w_b;
  ReprojectionCamera camera;
  Eigen::Vector3d p_w;
  Eigen::Vector3d p_c;
};

Configuration randomConfiguration(std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const auto vector = [&](double scale) -> Eigen::Vector3d {
    return Eigen::Vector3d(unit(rng), unit(rng), unit(rng)) * scale;
  };
  Configuration c;
  c.T_w_b = SE3d(expSO3(vector(M_PI)), vector(10.0));
  c.camera.T_b_c = SE3d(expSO3(vector(1.5)), vector(0.2));
  c.camera.fx = 450.0 + 50.0 * unit(rng);
  c.camera.fy = 450.0 + 50.0 * unit(rng);
  c.camera.baseline_m = 0.11;
  c.p_c = Eigen::Vector3d(2.0 * unit(rng), 1.5 * unit(rng), 3.0 + 2.5 * unit(rng));
  c.p_w = c.T_w_b * (c.camera.T_b_c * c.p_c);
  return c;
}

Eigen::Vector2d normalizedOf(const Eigen::Vector3d& p_c) {
  return p_c.head<2>() / p_c.z();
}

/// Residual and Jacobians of a factor at a pose block and a point (row-major ambient Jacobians).
template <int Rows>
struct Evaluation {
  Eigen::Matrix<double, Rows, 1> residual;
  Eigen::Matrix<double, Rows, 7, Eigen::RowMajor> J_pose;
  Eigen::Matrix<double, Rows, 3, Eigen::RowMajor> J_point;
  bool ok = false;
};

template <int Rows>
Evaluation<Rows> evaluate(const ceres::CostFunction& factor, const double* pose,
                          const double* point) {
  Evaluation<Rows> out;
  const double* parameters[] = {pose, point};
  double* jacobians[] = {out.J_pose.data(), out.J_point.data()};
  out.ok = factor.Evaluate(parameters, out.residual.data(), jacobians);
  return out;
}

template <int Rows>
Eigen::Matrix<double, Rows, 1> residualAt(const ceres::CostFunction& factor, const double* pose,
                                          const double* point) {
  Eigen::Matrix<double, Rows, 1> r;
  const double* parameters[] = {pose, point};
  EXPECT_TRUE(factor.Evaluate(parameters, r.data(), nullptr));
  return r;
}

/// Central differences of the residual in the tangent space of the pose (via the manifold's Plus)
/// and in the point coordinates: [J_tangent (Rows x 6), J_point (Rows x 3)].
template <int Rows>
Eigen::Matrix<double, Rows, 9> numericTangentJacobian(const ceres::CostFunction& factor,
                                                      const PoseBlock& pose,
                                                      const Eigen::Vector3d& p_w) {
  constexpr double kStep = 1e-6;
  const SE3Manifold manifold;
  Eigen::Matrix<double, Rows, 9> J;
  for (int k = 0; k < 6; ++k) {
    Vector6d delta = Vector6d::Zero();
    PoseBlock plus{}, minus{};
    delta(k) = kStep;
    manifold.Plus(pose.data(), delta.data(), plus.data());
    delta(k) = -kStep;
    manifold.Plus(pose.data(), delta.data(), minus.data());
    J.col(k) = (residualAt<Rows>(factor, plus.data(), p_w.data()) -
                residualAt<Rows>(factor, minus.data(), p_w.data())) /
               (2.0 * kStep);
  }
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d plus = p_w, minus = p_w;
    plus(k) += kStep;
    minus(k) -= kStep;
    J.col(6 + k) = (residualAt<Rows>(factor, pose.data(), plus.data()) -
                    residualAt<Rows>(factor, pose.data(), minus.data())) /
                   (2.0 * kStep);
  }
  return J;
}

/// Central differences in the 7 ambient coordinates of the pose block (exact because the factor
/// normalises the quaternion).
template <int Rows>
Eigen::Matrix<double, Rows, 7> numericAmbientJacobian(const ceres::CostFunction& factor,
                                                      const PoseBlock& pose,
                                                      const Eigen::Vector3d& p_w) {
  constexpr double kStep = 1e-6;
  Eigen::Matrix<double, Rows, 7> J;
  for (int k = 0; k < 7; ++k) {
    PoseBlock plus = pose, minus = pose;
    plus[static_cast<std::size_t>(k)] += kStep;
    minus[static_cast<std::size_t>(k)] -= kStep;
    J.col(k) = (residualAt<Rows>(factor, plus.data(), p_w.data()) -
                residualAt<Rows>(factor, minus.data(), p_w.data())) /
               (2.0 * kStep);
  }
  return J;
}

/// Checks the analytic Jacobians of a factor at one configuration; returns the largest relative
/// error (|J_analytic - J_numeric| / max(1, |J_numeric|), Frobenius norms).
template <int Rows>
double jacobianError(const ceres::CostFunction& factor, const Configuration& c) {
  const PoseBlock pose = toPoseBlock(c.T_w_b);
  const Evaluation<Rows> analytic = evaluate<Rows>(factor, pose.data(), c.p_w.data());
  EXPECT_TRUE(analytic.ok);
  Eigen::Matrix<double, Rows, 9> J_tangent;
  J_tangent.template leftCols<6>() = analytic.J_pose * posePlusJacobian(pose.data());
  J_tangent.template rightCols<3>() = analytic.J_point;
  const Eigen::Matrix<double, Rows, 9> numeric = numericTangentJacobian<Rows>(factor, pose, c.p_w);
  const Eigen::Matrix<double, Rows, 7> numeric_ambient =
      numericAmbientJacobian<Rows>(factor, pose, c.p_w);
  const auto relative = [](const auto& error, const auto& reference) {
    return error.norm() / std::max(1.0, reference.norm());
  };
  return std::max(
      relative(J_tangent - numeric, numeric),
      relative(Eigen::Matrix<double, Rows, 7>(analytic.J_pose) - numeric_ambient, numeric_ambient));
}

TEST(StereoBaseline, IsTheDistanceBetweenTheFirstTwoCamerasWhateverTheBodyFrame) {
  // EuRoC-like rig: cameras rotated against the body and offset from its origin.
  const Eigen::Quaterniond R_b_c(Eigen::AngleAxisd(0.5 * M_PI, Eigen::Vector3d::UnitZ()));
  const SE3d T_b_c0(R_b_c, Eigen::Vector3d(-0.02, -0.06, 0.01));
  const SE3d T_b_c1 = T_b_c0 * SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.11, 0, 0));
  const ReprojectionCamera left{T_b_c0, 450.0, 450.0};
  const ReprojectionCamera right{T_b_c1, 450.0, 450.0};
  EXPECT_NEAR(stereoBaseline({left, right}), 0.11, 1e-12);
  EXPECT_NEAR(stereoBaseline({right, left}), 0.11, 1e-12);
  EXPECT_EQ(stereoBaseline({left}), 0.0);
}

TEST(ReprojectionFactorTest, ResidualIsZeroAtTheTruth) {
  std::mt19937 rng(1);
  for (int trial = 0; trial < 20; ++trial) {
    const Configuration c = randomConfiguration(rng);
    const ReprojectionFactor mono(normalizedOf(c.p_c), c.camera, 1.0);
    const Eigen::Vector3d stereo_observed(c.p_c.x() / c.p_c.z(), c.p_c.y() / c.p_c.z(),
                                          (c.p_c.x() - c.camera.baseline_m) / c.p_c.z());
    const StereoReprojectionFactor stereo(stereo_observed, c.camera, 1.0);
    EXPECT_LT(mono.residual(c.T_w_b, c.p_w)->norm(), 1e-9);
    EXPECT_LT(stereo.residual(c.T_w_b, c.p_w)->norm(), 1e-9);
    const PoseBlock pose = toPoseBlock(c.T_w_b);
    EXPECT_LT(residualAt<2>(mono, pose.data(), c.p_w.data()).norm(), 1e-9);
    EXPECT_LT((worldToCamera(c.T_w_b, c.camera.T_b_c, c.p_w) - c.p_c).norm(), 1e-12);
  }
}

TEST(ReprojectionFactorTest, ResidualIsThePixelErrorOverTheOctaveSigma) {
  ReprojectionCamera camera;
  camera.fx = 400.0;
  camera.fy = 500.0;
  const Eigen::Vector3d p_w(0.2, -0.1, 4.0);  // body = camera = world
  const Eigen::Vector2d observed = normalizedOf(p_w) + Eigen::Vector2d(3.0 / 400.0, -2.0 / 500.0);
  const double sigma = octaveSigmaPx(2);  // 1.44 px
  EXPECT_NEAR(sigma, 1.44, 1e-12);
  const Eigen::Vector2d r = *ReprojectionFactor(observed, camera, sigma).residual(SE3d(), p_w);
  EXPECT_NEAR(r.x(), 3.0 / 1.44, 1e-9);
  EXPECT_NEAR(r.y(), -2.0 / 1.44, 1e-9);
}

TEST(ReprojectionFactorTest, AnalyticJacobiansMatchCentralDifferences) {
  std::mt19937 rng(2);
  double worst_mono = 0.0, worst_stereo = 0.0;
  for (int trial = 0; trial < 50; ++trial) {
    const Configuration c = randomConfiguration(rng);
    // Off the truth, so the residual is not zero.
    const Eigen::Vector2d observed = normalizedOf(c.p_c) + Eigen::Vector2d(0.01, -0.02);
    const ReprojectionFactor mono(observed, c.camera, octaveSigmaPx(trial % 4));
    const StereoReprojectionFactor stereo(Eigen::Vector3d(observed.x(), observed.y(), -0.03),
                                          c.camera, octaveSigmaPx(trial % 4));
    worst_mono = std::max(worst_mono, jacobianError<2>(mono, c));
    worst_stereo = std::max(worst_stereo, jacobianError<3>(stereo, c));
  }
  RecordProperty("worst_relative_error_mono", std::to_string(worst_mono));
  RecordProperty("worst_relative_error_stereo", std::to_string(worst_stereo));
  std::printf("worst relative Jacobian error: mono %.3g, stereo %.3g\n", worst_mono, worst_stereo);
  EXPECT_LT(worst_mono, 1e-6);
  EXPECT_LT(worst_stereo, 1e-6);
}

TEST(ReprojectionFactorTest, AmbientJacobianIgnoresTheQuaternionNorm) {
  std::mt19937 rng(3);
  const Configuration c = randomConfiguration(rng);
  const ReprojectionFactor factor(normalizedOf(c.p_c) + Eigen::Vector2d(0.01, 0.0), c.camera, 1.0);
  PoseBlock pose = toPoseBlock(c.T_w_b);
  for (int k = 0; k < 4; ++k)
    pose[static_cast<std::size_t>(k)] *= 1.7;  // non-unit quaternion
  const Evaluation<2> e = evaluate<2>(factor, pose.data(), c.p_w.data());
  const Eigen::Vector4d q(pose[0], pose[1], pose[2], pose[3]);
  EXPECT_LT((e.J_pose.leftCols<4>() * q).norm(), 1e-9);  // no change along the radial direction
  EXPECT_LT((e.residual - *factor.residual(c.T_w_b, c.p_w)).norm(), 1e-9);
}

TEST(ReprojectionFactorTest, PointsBehindTheCameraFailToEvaluate) {
  ReprojectionCamera camera;
  const ReprojectionFactor factor(Eigen::Vector2d::Zero(), camera, 1.0);
  const Eigen::Vector3d behind(0.1, 0.0, -2.0);
  EXPECT_FALSE(factor.residual(SE3d(), behind).has_value());
  const PoseBlock pose = toPoseBlock(SE3d());
  const double* parameters[] = {pose.data(), behind.data()};
  Eigen::Vector2d r;
  EXPECT_FALSE(factor.Evaluate(parameters, r.data(), nullptr));
}

TEST(ReprojectionFactorTest, RejectsInvalidCamerasAndSigmas) {
  ReprojectionCamera camera;
  camera.fx = 0.0;
  EXPECT_THROW(ReprojectionFactor(Eigen::Vector2d::Zero(), camera, 1.0), OptionError);
  camera.fx = 400.0;
  EXPECT_THROW(ReprojectionFactor(Eigen::Vector2d::Zero(), camera, 0.0), OptionError);
  EXPECT_THROW(StereoReprojectionFactor(Eigen::Vector3d::Zero(), camera, 1.0),
               OptionError);  // no baseline
  const CameraModel model(640, 480, 458.0, 457.0, 367.0, 248.0);
  const ReprojectionCamera from_model = ReprojectionCamera::from(model, SE3d(), 0.11);
  EXPECT_EQ(from_model.fx, 458.0);
  EXPECT_EQ(from_model.fy, 457.0);
}

TEST(ReprojectionFactorTest, HuberLossIsQuadraticUpToTheChiSquareThreshold) {
  const std::unique_ptr<ceres::LossFunction> loss(newHuberLoss(kChi2Mono95));
  double rho[3];
  loss->Evaluate(4.0, rho);
  EXPECT_DOUBLE_EQ(rho[0], 4.0);
  loss->Evaluate(100.0, rho);
  EXPECT_NEAR(rho[0], 2.0 * std::sqrt(kChi2Mono95 * 100.0) - kChi2Mono95, 1e-12);
}

TEST(ReprojectionFactorTest, PlusPoseIsTheManifoldPlusWithTheDoubledRotation) {
  std::mt19937 rng(4);
  const Configuration c = randomConfiguration(rng);
  const PoseBlock block = toPoseBlock(c.T_w_b);
  // plusPose is the manifold's Plus: Ceres' quaternion manifold rotates by twice the tangent.
  Vector6d delta;
  delta << 0.01, -0.02, 0.03, 0.1, 0.2, -0.3;
  PoseBlock plus{};
  SE3Manifold().Plus(block.data(), delta.data(), plus.data());
  const SE3d expected = fromPoseBlock(plus.data());
  const SE3d actual = plusPose(c.T_w_b, delta);
  EXPECT_LT(rotationAngle(expected.rotation().transpose() * actual.rotation()), 1e-12);
  EXPECT_LT((expected.t - actual.t).norm(), 1e-12);
  // The lifted rotation Jacobian times Ceres' PlusJacobian is twice the rotation-vector Jacobian.
  const Eigen::Matrix<double, 3, 4> J_q = rotationTangentFromQuaternion(block.data());
  const Eigen::Matrix<double, 7, 6> P = posePlusJacobian(block.data());
  EXPECT_LT((J_q * P.topLeftCorner<4, 3>() - 2.0 * Eigen::Matrix3d::Identity()).norm(), 1e-12);
}

}  // namespace
}  // namespace superdyna::optim

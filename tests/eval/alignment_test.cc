#include "superdyna/eval/alignment.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "eval_test_data.h"
#include "superdyna/core/error.h"
#include "support/test_support.h"

namespace superdyna::eval {
namespace {

Eigen::Matrix3Xd positionsOf(const Trajectory& trajectory) {
  Eigen::Matrix3Xd positions(3, static_cast<Eigen::Index>(trajectory.size()));
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    positions.col(static_cast<Eigen::Index>(i)) = trajectory[i].T_w_x.t;
  }
  return positions;
}

void expectSameSim3(const Sim3d& actual, const Sim3d& expected, double tolerance) {
  EXPECT_NEAR(actual.s / expected.s, 1.0, tolerance);
  EXPECT_LT((actual.R - expected.R).cwiseAbs().maxCoeff(), tolerance) << actual.R;
  EXPECT_LT((actual.t - expected.t).cwiseAbs().maxCoeff(), tolerance) << actual.t.transpose();
}

TEST(AlignmentTest, RecoversKnownSim3AndSE3OnEuroc) {
  SUPERDYNA_REQUIRE_SHARED(file, testdata::kMh01);
  const Trajectory gt = testdata::readSubsampled(file, 20);
  ASSERT_GT(gt.size(), 1000u);
  std::mt19937 rng(2024);
  for (int trial = 0; trial < 5; ++trial) {
    for (const bool unit_scale : {false, true}) {
      const Sim3d T_gt_est = testdata::randomSim3(rng, unit_scale);
      // The estimate lives in its own frame: est = T^-1 * gt, so aligning est to gt must give T.
      const Trajectory est = testdata::transformed(T_gt_est.inverse(), gt);
      const AlignmentMode mode = unit_scale ? AlignmentMode::kSE3 : AlignmentMode::kSim3;
      const Sim3d found = alignPositions(positionsOf(est), positionsOf(gt), mode);
      expectSameSim3(found, T_gt_est, 1e-9);
      EXPECT_NEAR(found.R.determinant(), 1.0, 1e-12);
    }
  }
}

TEST(AlignmentTest, SE3KeepsUnitScaleOnScaledData) {
  SUPERDYNA_REQUIRE_SHARED(file, testdata::kMh01);
  const Trajectory gt = testdata::readSubsampled(file, 50);
  Sim3d T;
  T.s = 0.5;
  const Trajectory est = testdata::transformed(T, gt);
  EXPECT_DOUBLE_EQ(alignPositions(positionsOf(est), positionsOf(gt), AlignmentMode::kSE3).s, 1.0);
  EXPECT_NEAR(alignPositions(positionsOf(est), positionsOf(gt), AlignmentMode::kSim3).s, 2.0, 1e-9);
}

TEST(AlignmentTest, AgreesWithEigenUmeyamaOnNoisyData) {
  SUPERDYNA_REQUIRE_SHARED(file, testdata::kMh01);
  const Trajectory gt = testdata::readSubsampled(file, 20);
  std::mt19937 rng(5);
  const Trajectory est = testdata::perturbed(
      testdata::transformed(testdata::randomSim3(rng, false), gt), 0.05, 0.0, 9);
  for (const bool with_scale : {false, true}) {
    const Eigen::Matrix4d reference = Eigen::umeyama(positionsOf(est), positionsOf(gt), with_scale);
    const Sim3d found = umeyamaAlignment(positionsOf(est), positionsOf(gt), with_scale);
    const double s = reference.topLeftCorner<3, 3>().col(0).norm();
    EXPECT_NEAR(found.s, s, 1e-9);
    EXPECT_LT((found.s * found.R - reference.topLeftCorner<3, 3>()).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_LT((found.t - reference.topRightCorner<3, 1>()).cwiseAbs().maxCoeff(), 1e-9);
  }
}

TEST(AlignmentTest, MirroredPointsStillGiveAProperRotation) {
  // A mirror image cannot be reached by a rotation; without the det-sign fix Umeyama returns a
  // reflection (det -1).
  Eigen::Matrix3Xd src(3, 5);
  src << 0, 1, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 0, 1, 1;
  const Eigen::Matrix3Xd dst = Eigen::Vector3d(1, 1, -1).asDiagonal() * src;
  const Sim3d found = umeyamaAlignment(src, dst, true);
  EXPECT_NEAR(found.R.determinant(), 1.0, 1e-12);
  EXPECT_NEAR((found.R * found.R.transpose() - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-12);
  EXPECT_GT(found.s, 0.0);
  // The least-squares optimum among proper rotations, with the scale trace(D S) / sigma^2 where S
  // carries the flipped sign: Eigen's independent implementation agrees.
  const Eigen::Matrix4d reference = Eigen::umeyama(src, dst, true);
  const double s = reference.topLeftCorner<3, 3>().col(0).norm();
  EXPECT_NEAR(found.s, s, 1e-12);
  EXPECT_LT((found.s * found.R - reference.topLeftCorner<3, 3>()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((found.t - reference.topRightCorner<3, 1>()).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(AlignmentTest, FirstNUsesOnlyTheFirstPoses) {
  SUPERDYNA_REQUIRE_SHARED(file, testdata::kMh01);
  const Trajectory gt = testdata::readSubsampled(file, 20);
  std::mt19937 rng(77);
  const Sim3d T_gt_est = testdata::randomSim3(rng, false);
  Trajectory est = testdata::transformed(T_gt_est.inverse(), gt);
  constexpr int kFirst = 150;
  // After the first kFirst poses the estimate drifts away; only the start is consistent with T.
  for (std::size_t i = kFirst; i < est.size(); ++i) {
    est[i].T_w_x.t += Eigen::Vector3d(0.01, -0.02, 0.005) * static_cast<double>(i - kFirst);
  }
  const Sim3d first =
      alignPositions(positionsOf(est), positionsOf(gt), AlignmentMode::kSim3, kFirst);
  expectSameSim3(first, T_gt_est, 1e-9);
  const Sim3d all = alignPositions(positionsOf(est), positionsOf(gt), AlignmentMode::kSim3, 0);
  EXPECT_GT((all.t - T_gt_est.t).norm(), 1e-3);
  // N larger than the trajectory means all poses.
  const Sim3d beyond = alignPositions(positionsOf(est), positionsOf(gt), AlignmentMode::kSim3,
                                      static_cast<int>(est.size()) + 10);
  EXPECT_LT((beyond.t - all.t).norm(), 1e-12);
}

TEST(AlignmentTest, NoneIsIdentity) {
  const Eigen::Matrix3Xd points = Eigen::Matrix3Xd::Random(3, 2);
  const Sim3d identity = alignPositions(points, points * 2.0, AlignmentMode::kNone);
  EXPECT_EQ(identity.s, 1.0);
  EXPECT_TRUE(identity.R.isIdentity());
  EXPECT_TRUE(identity.t.isZero());
}

TEST(AlignmentTest, DegenerateInputIsAnError) {
  Eigen::Matrix3Xd two(3, 2);
  two << 0, 1, 0, 1, 0, 0;
  EXPECT_THROW(umeyamaAlignment(two, two, false), InputError);

  Eigen::Matrix3Xd line(3, 10);
  for (int i = 0; i < 10; ++i)
    line.col(i) = Eigen::Vector3d(1, 2, 3) + i * Eigen::Vector3d(0.3, -0.1, 0.2);
  EXPECT_THROW(umeyamaAlignment(line, line, false), InputError);
  EXPECT_THROW(alignPositions(line, line, AlignmentMode::kSim3), InputError);

  const Eigen::Matrix3Xd same = Eigen::Vector3d(4, 5, 6).replicate(1, 8);
  try {
    umeyamaAlignment(same, same, true);
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("coincide"), std::string::npos) << e.what();
  }

  Eigen::Matrix3Xd plane = Eigen::Matrix3Xd::Random(3, 10);
  EXPECT_THROW(umeyamaAlignment(plane, plane.leftCols(9), false), InputError);
  EXPECT_THROW(alignPositions(plane, plane, AlignmentMode::kSE3, 2), InputError);
}

TEST(AlignmentTest, ParsesModeNames) {
  EXPECT_EQ(parseAlignmentMode("SE3"), AlignmentMode::kSE3);
  EXPECT_EQ(parseAlignmentMode("sim3"), AlignmentMode::kSim3);
  EXPECT_EQ(parseAlignmentMode("none"), AlignmentMode::kNone);
  EXPECT_EQ(toString(AlignmentMode::kSim3), "sim3");
  EXPECT_THROW(parseAlignmentMode("affine"), OptionError);
}

}  // namespace
}  // namespace superdyna::eval

// ATE and RPE against computations written out plainly with 4x4 matrices, and against cases whose
// answer is known in closed form.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "eval_test_data.h"
#include "superdyna/core/error.h"
#include "superdyna/eval/ate.h"
#include "superdyna/eval/evaluate.h"
#include "superdyna/eval/rpe.h"
#include "support/test_support.h"

namespace superdyna::eval {
namespace {

constexpr double kDeg = 180.0 / std::numbers::pi;

Eigen::Matrix4d homogeneous(const SE3d& pose, double position_scale = 1.0) {
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  M.topLeftCorner<3, 3>() = pose.q.toRotationMatrix();
  M.topRightCorner<3, 1>() = position_scale * pose.t;
  return M;
}

double angleDeg(const Eigen::Matrix3d& R) {
  const double c = std::clamp((R.trace() - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c) * kDeg;
}

struct Plain {
  double rmse = 0, mean = 0, median = 0, std = 0, max = 0;
  std::size_t count = 0;
};

Plain plainStatistics(std::vector<double> e) {
  Plain p;
  p.count = e.size();
  double sum = 0, sum_sq = 0;
  for (double v : e) {
    sum += v;
    sum_sq += v * v;
  }
  p.mean = sum / e.size();
  p.rmse = std::sqrt(sum_sq / e.size());
  double dev = 0;
  for (double v : e)
    dev += (v - p.mean) * (v - p.mean);
  p.std = std::sqrt(dev / e.size());
  std::sort(e.begin(), e.end());
  p.median = e.size() % 2 ? e[e.size() / 2] : 0.5 * (e[e.size() / 2 - 1] + e[e.size() / 2]);
  p.max = e.back();
  return p;
}

void expectStatistics(const ErrorStatistics& actual, const Plain& expected, double tolerance) {
  EXPECT_EQ(actual.count, expected.count);
  EXPECT_NEAR(actual.rmse, expected.rmse, tolerance);
  EXPECT_NEAR(actual.mean, expected.mean, tolerance);
  EXPECT_NEAR(actual.median, expected.median, tolerance);
  EXPECT_NEAR(actual.std, expected.std, tolerance);
  EXPECT_NEAR(actual.max, expected.max, tolerance);
}

/// Plain RPE: explicit matrices, linear search for j, E = (G_i^-1 G_j)^-1 (P_i^-1 P_j).
void plainRpe(const Trajectory& gt, const Trajectory& est, double scale, double delta, bool metres,
              std::vector<double>& trans, std::vector<double>& rot) {
  std::vector<double> travelled(gt.size(), 0.0);
  for (std::size_t k = 1; k < gt.size(); ++k) {
    travelled[k] = travelled[k - 1] + (gt[k].T_w_x.t - gt[k - 1].T_w_x.t).norm();
  }
  for (std::size_t i = 0; i < gt.size(); ++i) {
    std::size_t j = gt.size();
    if (metres) {
      for (std::size_t k = i + 1; k < gt.size(); ++k) {
        if (travelled[k] - travelled[i] >= delta) {
          j = k;
          break;
        }
      }
    } else if (i + static_cast<std::size_t>(delta) < gt.size()) {
      j = i + static_cast<std::size_t>(delta);
    }
    if (j == gt.size()) continue;
    const Eigen::Matrix4d G = homogeneous(gt[i].T_w_x).inverse() * homogeneous(gt[j].T_w_x);
    const Eigen::Matrix4d P =
        homogeneous(est[i].T_w_x, scale).inverse() * homogeneous(est[j].T_w_x, scale);
    const Eigen::Matrix4d E = G.inverse() * P;
    const double normaliser = metres ? delta : 1.0;
    trans.push_back(E.topRightCorner<3, 1>().norm() / normaliser);
    rot.push_back(angleDeg(E.topLeftCorner<3, 3>()) / normaliser);
  }
}

TEST(MetricsTest, PerturbedEurocMatchesPlainComputation) {
  SUPERDYNA_REQUIRE_SHARED(file, testdata::kMh01);
  const Trajectory gt = testdata::readSubsampled(file, 10);
  std::mt19937 rng(3);
  const Trajectory est = testdata::perturbed(
      testdata::transformed(testdata::randomSim3(rng, false), gt), 0.03, 0.01, 21);

  for (const DeltaUnit unit : {DeltaUnit::kMeters, DeltaUnit::kFrames}) {
    EvaluationOptions options;
    options.align = AlignmentMode::kSim3;
    options.rpe.unit = unit;
    options.rpe.delta = unit == DeltaUnit::kMeters ? 1.0 : 10.0;
    const EvaluationResult result = evaluate(gt, est, options);
    ASSERT_EQ(result.pairs, gt.size());  // same timestamps

    // Alignment by Eigen's independent Umeyama implementation.
    Eigen::Matrix3Xd src(3, est.size()), dst(3, gt.size());
    for (std::size_t i = 0; i < gt.size(); ++i) {
      src.col(i) = est[i].T_w_x.t;
      dst.col(i) = gt[i].T_w_x.t;
    }
    const Eigen::Matrix4d T = Eigen::umeyama(src, dst, true);
    const Eigen::Matrix3d sR = T.topLeftCorner<3, 3>();
    const double s = sR.col(0).norm();
    const Eigen::Matrix3d R = sR / s;
    EXPECT_NEAR(result.scale(), s, 1e-9);

    std::vector<double> ate_trans, ate_rot;
    for (std::size_t i = 0; i < gt.size(); ++i) {
      const Eigen::Matrix4d P = homogeneous(est[i].T_w_x);
      const Eigen::Vector3d aligned = sR * P.topRightCorner<3, 1>() + T.topRightCorner<3, 1>();
      ate_trans.push_back((gt[i].T_w_x.t - aligned).norm());
      const Eigen::Matrix3d R_gt = homogeneous(gt[i].T_w_x).topLeftCorner<3, 3>();
      ate_rot.push_back(angleDeg(R_gt.transpose() * R * P.topLeftCorner<3, 3>()));
    }
    expectStatistics(result.ate_trans, plainStatistics(ate_trans), 1e-9);
    expectStatistics(result.ate_rot, plainStatistics(ate_rot), 1e-6);
    EXPECT_LT((result.poses[7].aligned_position - (sR * est[7].T_w_x.t + T.topRightCorner<3, 1>()))
                  .norm(),
              1e-9);

    std::vector<double> rpe_trans, rpe_rot;
    plainRpe(gt, est, s, options.rpe.delta, unit == DeltaUnit::kMeters, rpe_trans, rpe_rot);
    expectStatistics(result.rpe_trans, plainStatistics(rpe_trans), 1e-9);
    expectStatistics(result.rpe_rot, plainStatistics(rpe_rot), 1e-6);
  }
}

/// Ground truth moves along x at 0.5 m per frame with identity rotation. The estimate travels k
/// times as far per frame and rolls (rotates about x, the direction of travel) by theta per frame,
/// so for pairs n frames apart: trans(E) = (k - 1) * 0.5 n along x and angle(E) = n * theta.
struct ConstantVelocityCase {
  static constexpr double kStep = 0.5;
  static constexpr double kScaleError = 1.1;
  static constexpr double kRollDeg = 0.5;
  static constexpr int kFrames = 40;

  std::vector<SE3d> gt, est;
  ConstantVelocityCase() {
    for (int i = 0; i < kFrames; ++i) {
      gt.emplace_back(Eigen::Matrix3d::Identity(), Eigen::Vector3d(kStep * i, 0, 0));
      const Eigen::Matrix3d roll = expSO3(Eigen::Vector3d(i * kRollDeg / kDeg, 0, 0));
      est.emplace_back(roll, Eigen::Vector3d(kScaleError * kStep * i, 0, 0));
    }
  }
};

TEST(MetricsTest, RpeInFramesOnConstantVelocity) {
  const ConstantVelocityCase c;
  RpeOptions options;
  options.unit = DeltaUnit::kFrames;
  options.delta = 2;
  const RpeResult rpe = computeRpe(c.gt, c.est, 1.0, options);
  EXPECT_EQ(rpe.pairs.size(), static_cast<std::size_t>(c.kFrames - 2));
  EXPECT_EQ(rpe.pairs.front(), std::make_pair(std::size_t{0}, std::size_t{2}));
  EXPECT_NEAR(rpe.trans.rmse, 0.1, 1e-12);  // (1.1 - 1) * 2 frames * 0.5 m
  EXPECT_NEAR(rpe.trans.max - rpe.trans.min, 0.0, 1e-12);
  EXPECT_NEAR(rpe.rot.rmse, 1.0, 1e-9);  // 2 frames * 0.5 deg
  EXPECT_EQ(rpeTransUnit(options.unit), "m");
  EXPECT_EQ(rpeRotUnit(options.unit), "deg");

  // Undoing the scale error leaves only the rotation.
  const RpeResult rescaled = computeRpe(c.gt, c.est, 1.0 / c.kScaleError, options);
  EXPECT_NEAR(rescaled.trans.rmse, 0.0, 1e-12);
  EXPECT_NEAR(rescaled.rot.rmse, 1.0, 1e-9);
}

TEST(MetricsTest, RpeInMetresIsNormalisedByDelta) {
  const ConstantVelocityCase c;
  RpeOptions options;
  options.unit = DeltaUnit::kMeters;
  options.delta = 2.0;  // 4 frames of 0.5 m
  const RpeResult rpe = computeRpe(c.gt, c.est, 1.0, options);
  EXPECT_EQ(rpe.pairs.size(), static_cast<std::size_t>(c.kFrames - 4));
  EXPECT_EQ(rpe.pairs.back(),
            std::make_pair(std::size_t{c.kFrames - 5}, std::size_t{c.kFrames - 1}));
  EXPECT_NEAR(rpe.trans.rmse, 0.1, 1e-12);  // 0.2 m over 2 m
  EXPECT_NEAR(rpe.trans.mean, 0.1, 1e-12);
  EXPECT_NEAR(rpe.rot.rmse, 1.0, 1e-9);  // 2 deg over 2 m
  EXPECT_EQ(rpeTransUnit(options.unit), "m/m");
  EXPECT_EQ(rpeRotUnit(options.unit), "deg/m");

  // 1.2 m is reached by the first pose at least 1.2 m further: 3 frames (1.5 m), still
  // normalised by the nominal 1.2 m as the KITTI devkit does.
  options.delta = 1.2;
  const RpeResult uneven = computeRpe(c.gt, c.est, 1.0, options);
  EXPECT_EQ(uneven.pairs.front(), std::make_pair(std::size_t{0}, std::size_t{3}));
  EXPECT_NEAR(uneven.trans.rmse, 0.15 / 1.2, 1e-12);
}

TEST(MetricsTest, RpeMetresToleratesRoundedPathSums) {
  // Positions advanced by 0.1 m at a time: the summed path to frame 10 rounds to just below 1 m.
  std::vector<SE3d> gt;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  for (int i = 0; i < 30; ++i) {
    gt.emplace_back(Eigen::Matrix3d::Identity(), position);
    position.x() += 0.1;
  }
  double travelled = 0.0;
  for (int k = 1; k <= 10; ++k)
    travelled += (gt[k].t - gt[k - 1].t).norm();
  ASSERT_LT(travelled, 1.0);  // the case this test is about
  const auto pairs = rpePosePairs(gt, RpeOptions{});
  ASSERT_FALSE(pairs.empty());
  EXPECT_EQ(pairs.front().second, 10u);
}

TEST(MetricsTest, AteOfConstantOffsetWithoutAlignment) {
  const ConstantVelocityCase c;
  std::vector<SE3d> est = c.gt;
  for (SE3d& pose : est)
    pose.t += Eigen::Vector3d(0.0, 0.3, 0.4);
  const AteResult ate = computeAte(c.gt, est, Sim3d{});
  EXPECT_NEAR(ate.trans.rmse, 0.5, 1e-12);
  EXPECT_NEAR(ate.trans.std, 0.0, 1e-12);
  EXPECT_NEAR(ate.rot.max, 0.0, 1e-12);
}

TEST(MetricsTest, BadRpeOptionsAndTooShortTrajectories) {
  const ConstantVelocityCase c;
  for (const double delta : {0.0, -1.0, std::nan("")}) {
    RpeOptions options;
    options.delta = delta;
    EXPECT_THROW(options.validate(), OptionError) << delta;
  }
  RpeOptions frames;
  frames.unit = DeltaUnit::kFrames;
  frames.delta = 1.5;
  EXPECT_THROW(computeRpe(c.gt, c.est, 1.0, frames), OptionError);

  RpeOptions too_far;
  too_far.delta = 100.0;  // the path is 19.5 m
  try {
    computeRpe(c.gt, c.est, 1.0, too_far);
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("19.500 m"), std::string::npos) << e.what();
  }
  EXPECT_THROW(computeRpe(c.gt, {c.est.begin(), c.est.end() - 1}, 1.0, RpeOptions{}), InputError);
  EXPECT_EQ(parseDeltaUnit("frames"), DeltaUnit::kFrames);
  EXPECT_EQ(parseDeltaUnit("M"), DeltaUnit::kMeters);
  EXPECT_THROW(parseDeltaUnit("s"), OptionError);
}

}  // namespace
}  // namespace superdyna::eval

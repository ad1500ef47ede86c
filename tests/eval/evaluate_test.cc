#include "superdyna/eval/evaluate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "eval_test_data.h"
#include "superdyna/core/error.h"
#include "superdyna/eval/multi_run.h"
#include "support/test_support.h"

namespace superdyna::eval {
namespace {

Trajectory shiftedInTime(const Trajectory& trajectory, TimeNs shift_ns) {
  Trajectory out = trajectory;
  for (StampedPose& pose : out)
    pose.t_ns += shift_ns;
  return out;
}

TEST(EvaluateTest, IdenticalTrajectoryHasZeroError) {
  SUPERDYNA_REQUIRE_SHARED(file, testdata::kMh01);
  const Trajectory gt = testdata::readSubsampled(file, 10);
  const EvaluationResult result = evaluate(gt, gt, EvaluationOptions{});
  EXPECT_EQ(result.pairs, gt.size());
  EXPECT_EQ(result.gt_poses, gt.size());
  EXPECT_EQ(result.est_poses, gt.size());
  EXPECT_EQ(result.poses.size(), gt.size());
  EXPECT_LT(result.ate_trans.max, 1e-9);
  EXPECT_LT(result.ate_rot.max, 1e-6);
  EXPECT_LT(result.rpe_trans.max, 1e-9);
  EXPECT_DOUBLE_EQ(result.scale(), 1.0);
  EXPECT_GT(result.rpe_trans.count, gt.size() / 2);
}

TEST(EvaluateTest, APathShorterThanTheRpeDeltaHasAnAteWhenRpeIsOptional) {
  // 2 cm of jitter around a standing rig (as the EuRoC excerpt's stationary start): no pose pair
  // is 1 m apart.
  Trajectory gt, est;
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d p(0.01 * std::sin(0.3 * i), 0.01 * std::cos(0.2 * i), 0.001 * i);
    gt.push_back({i * 50 * kNsPerMillisecond, SE3d(Eigen::Quaterniond::Identity(), p)});
    est.push_back({i * 50 * kNsPerMillisecond, SE3d(Eigen::Quaterniond::Identity(),
                                                    p + Eigen::Vector3d(0.001 * (i % 2), 0, 0))});
  }
  EvaluationOptions options;
  test::expectError([&] { evaluate(gt, est, options); }, {"RPE", "1 m apart"});
  options.require_rpe = false;
  const EvaluationResult result = evaluate(gt, est, options);
  EXPECT_NEAR(result.ate_trans.rmse, 0.0005, 1e-4);
  EXPECT_EQ(result.rpe_trans.count, 0u);
  EXPECT_NE(result.rpe_missing.find("1 m apart"), std::string::npos) << result.rpe_missing;
}

TEST(EvaluateTest, AnAlignmentRotationThePathDoesNotDetermineIsFlagged) {
  // A hover over a few centimetres with 3 mm of estimate noise: the rotation the alignment fits is
  // decided by the noise.
  Trajectory gt, est;
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.003);
  for (int i = 0; i < 95; ++i) {
    const Eigen::Vector3d p(0.02 * std::sin(0.05 * i), 0.002 * std::cos(0.3 * i),
                            0.001 * std::sin(0.2 * i));
    gt.push_back({i * 50 * kNsPerMillisecond, SE3d(Eigen::Quaterniond::Identity(), p)});
    const Eigen::Vector3d e(noise(rng), noise(rng), noise(rng));
    est.push_back({i * 50 * kNsPerMillisecond, SE3d(Eigen::Quaterniond::Identity(), p + e)});
  }
  EvaluationOptions options;
  options.require_rpe = false;
  const EvaluationResult hover = evaluate(gt, est, options);
  EXPECT_TRUE(hover.alignmentRotationUndetermined());
  EXPECT_GT(hover.alignment_rotation_uncertainty_deg, 30.0);
  // A 5 m circle with the same noise determines it to a fraction of a degree.
  Trajectory circle_gt, circle_est;
  for (int i = 0; i < 200; ++i) {
    const double a = 0.0314 * i;
    const Eigen::Vector3d p(5.0 * std::cos(a), 5.0 * std::sin(a), 0.3 * std::sin(3.0 * a));
    circle_gt.push_back({i * 50 * kNsPerMillisecond, SE3d(Eigen::Quaterniond::Identity(), p)});
    const Eigen::Vector3d e(noise(rng), noise(rng), noise(rng));
    circle_est.push_back({i * 50 * kNsPerMillisecond, SE3d(Eigen::Quaterniond::Identity(), p + e)});
  }
  const EvaluationResult circle = evaluate(circle_gt, circle_est, options);
  EXPECT_FALSE(circle.alignmentRotationUndetermined());
  EXPECT_LT(circle.alignment_rotation_uncertainty_deg, 0.2);
  // Nothing is estimated without an alignment or with a given one.
  options.align = AlignmentMode::kNone;
  EXPECT_EQ(evaluate(gt, est, options).alignment_rotation_uncertainty_deg, 0.0);
}

TEST(EvaluateTest, Sim3RecoversScaleAndRpeUsesIt) {
  SUPERDYNA_REQUIRE_SHARED(file, testdata::kMh01);
  const Trajectory gt = testdata::readSubsampled(file, 10);
  std::mt19937 rng(8);
  const Sim3d T = testdata::randomSim3(rng, false);
  const Trajectory est = testdata::transformed(T.inverse(), gt);  // a monocular run: unknown scale
  EvaluationOptions options;
  options.align = AlignmentMode::kSim3;
  const EvaluationResult result = evaluate(gt, est, options);
  EXPECT_NEAR(result.scale() / T.s, 1.0, 1e-9);
  EXPECT_LT(result.ate_trans.rmse, 1e-8);
  EXPECT_LT(result.rpe_trans.rmse, 1e-8);  // with the scale applied the motion is exact

  options.align = AlignmentMode::kSE3;
  EXPECT_GT(evaluate(gt, est, options).rpe_trans.rmse, 1e-3);  // scale left wrong
}

TEST(EvaluateTest, OffsetRepairsAShiftedClock) {
  SUPERDYNA_REQUIRE_SHARED(file, testdata::kMh01);
  const Trajectory gt = testdata::readSubsampled(file, 10);
  const TimeNs shift_ns = 300 * kNsPerMillisecond;
  const Trajectory est = shiftedInTime(gt, shift_ns);
  EvaluationOptions options;
  options.association.offset_ns = -shift_ns;
  const EvaluationResult result = evaluate(gt, est, options);
  EXPECT_EQ(result.pairs, gt.size());
  EXPECT_LT(result.ate_trans.max, 1e-9);
  EXPECT_EQ(result.poses.front().t_ns, gt.front().t_ns);  // reported on the ground-truth clock
}

TEST(EvaluateTest, TooFewAssociationsExplainsWhy) {
  Trajectory gt, est;
  for (int i = 0; i < 10; ++i) {
    const SE3d pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(i, i * i, 0));
    gt.push_back({(100 + i) * kNsPerSecond, pose});
    est.push_back({(200 + i) * kNsPerSecond, pose});
  }
  EvaluationOptions options;
  test::expectError<InputError>(
      [&] { evaluate(gt, est, options); },
      {"only 0 pose pairs", "10 poses from 100.000 s to 109.000 s",
       "10 poses from 200.000 s to 209.000 s", "--max-diff (now 10 ms)", "--offset (now 0 ms)"});
  test::expectError<InputError>([&] { evaluate(gt, {}, options); }, {"Estimate: no poses"});
  options.association.offset_ns = -100 * kNsPerSecond;
  EXPECT_EQ(evaluate(gt, est, options).pairs, 10u);
}

TEST(EvaluateTest, ValidateNamesTheOption) {
  EvaluationOptions options;
  options.association.max_diff_ns = -5;
  test::expectError<OptionError>([&] { options.validate(); }, {"max_diff_ns"});
  options = {};
  options.rpe.delta = 0.0;
  test::expectError<OptionError>([&] { options.validate(); }, {"delta"});
  options = {};
  options.align_first_n = 2;
  test::expectError<OptionError>([&] { options.validate(); }, {"align_first_n"});
  options.align = AlignmentMode::kNone;
  EXPECT_NO_THROW(options.validate());
  options.align_first_n = -1;  // all poses
  EXPECT_NO_THROW(options.validate());
}

TEST(EvaluateTest, StraightLineCannotBeAlignedButCanBeMeasuredUnaligned) {
  Trajectory line;
  for (int i = 0; i < 50; ++i) {
    line.push_back({i * 50 * kNsPerMillisecond,
                    SE3d(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.1 * i, 0, 0))});
  }
  test::expectError<InputError>([&] { evaluate(line, line, EvaluationOptions{}); }, {"one line"});
  EvaluationOptions unaligned;
  unaligned.align = AlignmentMode::kNone;
  EXPECT_LT(evaluate(line, line, unaligned).ate_trans.max, 1e-12);
}

TEST(EvaluateTest, MultiRunSummaryOverPerturbedRuns) {
  SUPERDYNA_REQUIRE_SHARED(file, testdata::kMh01);
  const Trajectory gt = testdata::readSubsampled(file, 20);
  std::vector<Trajectory> runs;
  for (std::uint32_t seed = 1; seed <= 5; ++seed) {
    runs.push_back(testdata::perturbed(gt, 0.01 * seed, 0.002, seed));
  }
  const MultiRunResult multi = evaluateRuns(gt, runs, EvaluationOptions{});
  ASSERT_EQ(multi.runs.size(), 5u);
  EXPECT_EQ(multi.runs[2].name, "run 3");
  std::vector<double> rmse;
  double mean = 0.0;
  for (const NamedRun& run : multi.runs) {
    rmse.push_back(run.result.ate_trans.rmse);
    mean += run.result.ate_trans.rmse / 5.0;
  }
  double squares = 0.0;
  for (double v : rmse)
    squares += (v - mean) * (v - mean);
  const double s = std::sqrt(squares / 4.0);
  EXPECT_NEAR(multi.ate_rmse.mean, mean, 1e-15);
  EXPECT_DOUBLE_EQ(multi.ate_rmse.median, rmse[2]);  // noise grows with the seed
  EXPECT_NEAR(multi.ate_rmse.std, s, 1e-15);
  EXPECT_NEAR(multi.ate_rmse.ci95_halfwidth, 2.7764451051977987 * s / std::sqrt(5.0), 1e-15);

  const MultiRunResult single = evaluateRuns(gt, {runs[0]}, EvaluationOptions{}, {"only"});
  EXPECT_EQ(single.runs[0].name, "only");
  EXPECT_TRUE(std::isnan(single.ate_rmse.ci95_halfwidth));
  EXPECT_THROW(evaluateRuns(gt, runs, EvaluationOptions{}, {"a", "b"}), OptionError);
  EXPECT_THROW(summarizeRuns({}), InputError);
  test::expectError<InputError>(
      [&] {
        evaluateRuns(gt, {runs[0], {}}, EvaluationOptions{});
      },
      {"run 2:"});
}

}  // namespace
}  // namespace superdyna::eval

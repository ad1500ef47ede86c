#include "superdyna/sim/se3_spline.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>

#include "superdyna/core/error.h"
#include "superdyna/io/trajectory_io.h"
#include "superdyna/sim/procedural_trajectory.h"
#include "support/test_support.h"

namespace superdyna::sim {
namespace {

constexpr TimeNs kT0Ns = 1'403'636'580'000'000'000;  // EuRoC-like epoch time.
constexpr TimeNs kKnotNs = 100'000'000;              // 0.1 s.

/// A lively spline: random-walk control points, ~1 m/s and ~2 rad/s, 40 knots.
Se3Spline randomSpline(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const auto gaussVector = [&](double sigma) {
    Eigen::Vector3d v;
    for (int axis = 0; axis < 3; ++axis) {
      v[axis] = sigma * gauss(rng);
    }
    return v;
  };
  std::vector<SE3d> controls;
  Eigen::Matrix3d R = expSO3(gaussVector(1.0));
  Eigen::Vector3d p = gaussVector(2.0);
  for (int k = 0; k < 40; ++k) {
    controls.emplace_back(R, p);
    R = R * expSO3(gaussVector(0.12));
    p += gaussVector(0.06);
  }
  return Se3Spline(kT0Ns, kKnotNs, controls);
}

/// Times inside segments, at least 5 ms from a knot so that central differences stay in one
/// polynomial piece.
std::vector<TimeNs> testTimes(const Se3Spline& spline) {
  std::vector<TimeNs> times;
  const TimeRange valid = spline.validRange();
  for (TimeNs knot = valid.begin; knot < valid.end; knot += spline.knotSpacingNs()) {
    for (const double u : {0.05, 0.31, 0.5, 0.77, 0.95}) {
      times.push_back(knot + std::llround(u * static_cast<double>(spline.knotSpacingNs())));
    }
  }
  return times;
}

constexpr TimeNs kStepNs = 100'000;  // Finite-difference step h = 0.1 ms.
constexpr double kStepS = 1e-4;

TEST(Se3SplineTest, VelocityAndAccelerationMatchFiniteDifferences) {
  const Se3Spline spline = randomSpline(7);
  double max_v_error = 0.0, max_a_error = 0.0, max_speed = 0.0;
  for (const TimeNs t : testTimes(spline)) {
    const Eigen::Vector3d v_fd =
        (spline.position(t + kStepNs) - spline.position(t - kStepNs)) / (2.0 * kStepS);
    const Eigen::Vector3d a_fd =
        (spline.velocity(t + kStepNs) - spline.velocity(t - kStepNs)) / (2.0 * kStepS);
    max_v_error = std::max(max_v_error, (spline.velocity(t) - v_fd).norm());
    max_a_error = std::max(max_a_error, (spline.acceleration(t) - a_fd).norm());
    max_speed = std::max(max_speed, spline.velocity(t).norm());
  }
  EXPECT_GT(max_speed, 0.5);  // The test motion really moves.
  EXPECT_LT(max_v_error, 1e-6) << "m/s";
  EXPECT_LT(max_a_error, 1e-6) << "m/s^2";
}

TEST(Se3SplineTest, AngularVelocityAndAccelerationMatchFiniteDifferences) {
  const Se3Spline spline = randomSpline(11);
  double max_w_error = 0.0, max_alpha_error = 0.0, max_rate = 0.0;
  for (const TimeNs t : testTimes(spline)) {
    const Eigen::Matrix3d R_minus = spline.rotation(t - kStepNs);
    const Eigen::Matrix3d R_plus = spline.rotation(t + kStepNs);
    const Eigen::Vector3d omega_fd = logSO3(R_minus.transpose() * R_plus) / (2.0 * kStepS);
    const Eigen::Vector3d alpha_fd =
        (spline.angularVelocity(t + kStepNs) - spline.angularVelocity(t - kStepNs)) /
        (2.0 * kStepS);
    max_w_error = std::max(max_w_error, (spline.angularVelocity(t) - omega_fd).norm());
    max_alpha_error = std::max(max_alpha_error, (spline.angularAcceleration(t) - alpha_fd).norm());
    max_rate = std::max(max_rate, spline.angularVelocity(t).norm());
  }
  EXPECT_GT(max_rate, 1.0);
  EXPECT_LT(max_w_error, 1e-5) << "rad/s";
  EXPECT_LT(max_alpha_error, 1e-4) << "rad/s^2";
}

TEST(Se3SplineTest, ForwardDifferenceOfRotationConvergesToAngularVelocity) {
  // omega_b = lim log(R(t)^T R(t + h)) / h: the first-order error shrinks tenfold with h.
  const Se3Spline spline = randomSpline(3);
  for (const TimeNs t : testTimes(spline)) {
    const Eigen::Vector3d omega = spline.angularVelocity(t);
    const Eigen::Matrix3d R_t = spline.rotation(t);
    const auto forwardError = [&](TimeNs h_ns) {
      const Eigen::Vector3d fd =
          logSO3(R_t.transpose() * spline.rotation(t + h_ns)) / nsToSeconds(h_ns);
      return (fd - omega).norm();
    };
    EXPECT_LT(forwardError(10'000), 2e-3) << t;
    EXPECT_LT(forwardError(10'000), 0.2 * forwardError(100'000) + 1e-7) << t;
  }
}

TEST(Se3SplineTest, EverythingIsContinuousAcrossKnots) {
  const Se3Spline spline = randomSpline(5);
  const TimeRange valid = spline.validRange();
  for (TimeNs knot = valid.begin + kKnotNs; knot < valid.end; knot += kKnotNs) {
    const Se3SplineState before = spline.state(knot - 1);  // Previous segment at u ~ 1.
    const Se3SplineState at = spline.state(knot);          // Next segment at u = 0.
    EXPECT_LT((before.T_w_b.t - at.T_w_b.t).norm(), 1e-8);
    EXPECT_LT(rotationAngle(before.T_w_b.rotation().transpose() * at.T_w_b.rotation()), 1e-8);
    EXPECT_LT((before.v_w - at.v_w).norm(), 1e-6);
    EXPECT_LT((before.a_w - at.a_w).norm(), 1e-5);
    EXPECT_LT((before.omega_b - at.omega_b).norm(), 1e-6);
    EXPECT_LT((before.alpha_b - at.alpha_b).norm(), 1e-4);
  }
}

TEST(Se3SplineTest, StateAgreesWithTheSeparateEvaluations) {
  const Se3Spline spline = randomSpline(9);
  for (const TimeNs t : testTimes(spline)) {
    const Se3SplineState s = spline.state(t);
    EXPECT_EQ(s.t_ns, t);
    EXPECT_LT((s.T_w_b.matrix() - spline.pose(t).matrix()).norm(), 1e-12);
    EXPECT_LT((s.v_w - spline.velocity(t)).norm(), 1e-12);
    EXPECT_LT((s.a_w - spline.acceleration(t)).norm(), 1e-12);
    EXPECT_LT((s.omega_b - spline.angularVelocity(t)).norm(), 1e-12);
    EXPECT_LT((s.alpha_b - spline.angularAcceleration(t)).norm(), 1e-12);
  }
}

TEST(Se3SplineTest, ConstantVelocityControlPointsGiveExactlyConstantVelocity) {
  const Eigen::Vector3d v_w(0.8, -0.3, 0.1);
  const Eigen::Vector3d omega_b(0.2, -0.5, 1.1);
  const Eigen::Matrix3d R0 = expSO3(Eigen::Vector3d(0.3, 0.2, -1.0));
  const Eigen::Vector3d p0(1.0, 2.0, 3.0);
  const auto poseAt = [&](TimeNs t_ns) {
    const double t = nsToSeconds(t_ns - kT0Ns);
    return SE3d(Eigen::Matrix3d(R0 * expSO3(t * omega_b)), Eigen::Vector3d(p0 + t * v_w));
  };
  const Se3Spline spline =
      Se3Spline::fromFunction(poseAt, {kT0Ns, kT0Ns + 2 * kNsPerSecond}, kKnotNs);
  EXPECT_EQ(spline.validRange().begin, kT0Ns);
  EXPECT_EQ(spline.validRange().end, kT0Ns + 2 * kNsPerSecond);
  for (TimeNs t = kT0Ns; t <= kT0Ns + 2 * kNsPerSecond; t += 37'000'000) {
    const Se3SplineState s = spline.state(t);
    const SE3d expected = poseAt(t);
    EXPECT_LT((s.T_w_b.t - expected.t).norm(), 1e-12);
    EXPECT_LT(rotationAngle(s.T_w_b.rotation().transpose() * expected.rotation()), 1e-12);
    EXPECT_LT((s.v_w - v_w).norm(), 1e-12);
    EXPECT_LT(s.a_w.norm(), 1e-10);
    EXPECT_LT((s.omega_b - omega_b).norm(), 1e-12);
    EXPECT_LT(s.alpha_b.norm(), 1e-10);
  }
}

TEST(Se3SplineTest, ValidRangeIsExactAndEvaluationOutsideThrows) {
  const Se3Spline spline = randomSpline(1);  // 40 control points.
  const TimeRange valid = spline.validRange();
  EXPECT_EQ(valid.begin, kT0Ns + kKnotNs);
  EXPECT_EQ(valid.end, kT0Ns + 38 * kKnotNs);
  EXPECT_NO_THROW(spline.state(valid.begin));
  EXPECT_NO_THROW(spline.state(valid.end));
  EXPECT_THROW(spline.pose(valid.begin - 1), OptionError);
  EXPECT_THROW(spline.velocity(valid.end + 1), OptionError);
  EXPECT_THROW(spline.angularVelocity(kT0Ns), OptionError);
  EXPECT_THROW(spline.state(valid.end + kKnotNs), OptionError);
}

TEST(Se3SplineTest, RejectsInvalidControlPoints) {
  const std::vector<SE3d> three(3);
  EXPECT_THROW(Se3Spline(0, kKnotNs, three), OptionError);
  const std::vector<SE3d> four(4);
  EXPECT_NO_THROW(Se3Spline(0, kKnotNs, four));
  EXPECT_THROW(Se3Spline(0, 0, four), OptionError);
  EXPECT_THROW(Se3Spline(0, -kKnotNs, four), OptionError);
  std::vector<SE3d> half_turn(4);
  half_turn[2] = SE3d(expSO3(Eigen::Vector3d(0.0, 0.0, M_PI)), Eigen::Vector3d::Zero());
  EXPECT_THROW(Se3Spline(0, kKnotNs, half_turn), OptionError);
  const auto still = [](TimeNs) { return SE3d(); };
  EXPECT_THROW(Se3Spline::fromFunction(still, {0, kNsPerSecond}, 0), OptionError);
  EXPECT_THROW(Se3Spline::fromFunction(still, {kNsPerSecond, 0}, kKnotNs), OptionError);
  EXPECT_EQ(Se3Spline::fromFunction(still, {0, 0}, kKnotNs).validRange().end, kKnotNs);
}

/// RMS and maximum of the position [m] and rotation [rad] errors of the spline at the samples
/// inside its valid range.
struct FitError {
  double position_rms = 0.0, position_max = 0.0;
  double rotation_rms = 0.0, rotation_max = 0.0;
  std::size_t count = 0;
};

FitError fitError(const Se3Spline& spline, const Trajectory& samples) {
  FitError e;
  for (const StampedPose& sample : samples) {
    if (!spline.validRange().contains(sample.t_ns)) continue;
    const SE3d T = spline.pose(sample.t_ns);
    const double dp = (T.t - sample.T_w_x.t).norm();
    const double dr = rotationAngle(T.rotation().transpose() * sample.T_w_x.rotation());
    e.position_rms += dp * dp;
    e.rotation_rms += dr * dr;
    e.position_max = std::max(e.position_max, dp);
    e.rotation_max = std::max(e.rotation_max, dr);
    ++e.count;
  }
  e.position_rms = std::sqrt(e.position_rms / static_cast<double>(e.count));
  e.rotation_rms = std::sqrt(e.rotation_rms / static_cast<double>(e.count));
  return e;
}

Trajectory excerpt(const Trajectory& trajectory, TimeNs begin_ns, TimeNs end_ns) {
  Trajectory out;
  for (const StampedPose& p : trajectory) {
    if (p.t_ns >= begin_ns && p.t_ns <= end_ns) out.push_back(p);
  }
  return out;
}

TEST(Se3SplineFitTest, ValidRangeStartsAtTheFirstSampleAndEndsAtTheLastKnotInside) {
  LissajousOptions options;
  options.duration_s = 10.05;
  options.rate_hz = 100.0;
  const Trajectory samples = makeLissajousTrajectory(options);
  const Se3Spline spline = Se3Spline::fit(samples, kKnotNs);
  EXPECT_EQ(spline.knotSpacingNs(), kKnotNs);
  EXPECT_EQ(spline.validRange().begin, samples.front().t_ns);
  EXPECT_EQ(spline.validRange().end, samples.front().t_ns + 100 * kKnotNs);
  EXPECT_EQ(spline.controlPoses().size(), 103u);
}

TEST(Se3SplineFitTest, FitsSmoothMotionToWellBelowAMillimetre) {
  LissajousOptions options;
  options.duration_s = 30.0;
  options.rate_hz = 100.0;
  options.period_s = 20.0;
  const Trajectory samples = makeLissajousTrajectory(options);
  const FitError e = fitError(Se3Spline::fit(samples, kKnotNs), samples);
  EXPECT_EQ(e.count, samples.size());
  // Measured: position max 1.9e-5 m, rotation max 0.0005 deg (9e-6 rad).
  EXPECT_LT(e.position_max, 5e-5);
  EXPECT_LT(e.rotation_max, 3e-5);
  std::cout << fmt::format(
      "[ info ] Lissajous fit: position RMS {:.2e} m max {:.2e} m, rotation "
      "RMS {:.4f} deg max {:.4f} deg\n",
      e.position_rms, e.position_max, e.rotation_rms * 180.0 / M_PI, e.rotation_max * 180.0 / M_PI);
}

TEST(Se3SplineFitTest, FitsThirtySecondsOfEurocGroundTruthWithinCentimetres) {
  SUPERDYNA_REQUIRE_SHARED(file, "data/trajectories/euroc/MH_01_easy.txt");
  const Trajectory all = io::readTrajectory(file);
  ASSERT_FALSE(all.empty());
  const TimeNs begin = all.front().t_ns + 40 * kNsPerSecond;  // After the initial shaking.
  const Trajectory samples = excerpt(all, begin, begin + 30 * kNsPerSecond);
  ASSERT_GT(samples.size(), 5000u);  // 200 Hz.
  const Se3Spline spline = Se3Spline::fit(samples, kKnotNs);
  const FitError e = fitError(spline, samples);
  std::cout << fmt::format(
      "[ info ] EuRoC MH_01 30 s, 0.1 s knots: {} samples, position RMS "
      "{:.2f} mm max {:.2f} mm, rotation RMS {:.3f} deg max {:.3f} deg\n",
      e.count, 1e3 * e.position_rms, 1e3 * e.position_max, e.rotation_rms * 180.0 / M_PI,
      e.rotation_max * 180.0 / M_PI);
  EXPECT_GT(e.count, samples.size() - 25);
  // Measured: position RMS 0.16 mm (max 1.2 mm), rotation RMS 0.041 deg (max 0.21 deg).
  EXPECT_LT(e.position_rms, 0.25e-3);
  EXPECT_LT(e.position_max, 2e-3);
  EXPECT_LT(e.rotation_rms * 180.0 / M_PI, 0.06);
  EXPECT_LT(e.rotation_max * 180.0 / M_PI, 0.3);
}

TEST(Se3SplineFitTest, FitsAnOpenLorisRecordingAfterSplittingAtItsGaps) {
  SUPERDYNA_REQUIRE_SHARED(file, "data/trajectories/openloris/cafe_1.txt");
  const Trajectory all = io::readTrajectory(file);
  EXPECT_THROW(Se3Spline::fit(all, kKnotNs), InputError);  // Hours between the recordings.
  const std::vector<Trajectory> parts = splitAtGaps(all, kNsPerSecond);
  ASSERT_GE(parts.size(), 2u);
  const Se3Spline spline = Se3Spline::fit(parts.front(), kKnotNs);
  const FitError e = fitError(spline, parts.front());
  std::cout << fmt::format(
      "[ info ] OpenLORIS cafe_1 part 1 ({} samples, {:.0f} s): position RMS "
      "{:.2f} mm max {:.2f} mm, rotation RMS {:.3f} deg\n",
      e.count, spline.validRange().durationSeconds(), 1e3 * e.position_rms, 1e3 * e.position_max,
      e.rotation_rms * 180.0 / M_PI);
  // Measured: position RMS 4.9 mm (max 37 mm: 30 Hz jitter), rotation RMS 0.063 deg.
  EXPECT_LT(e.position_rms, 6e-3);
  EXPECT_LT(e.position_max, 0.05);
  EXPECT_LT(e.rotation_rms * 180.0 / M_PI, 0.08);
}

TEST(Se3SplineFitTest, RejectsUnusableSamples) {
  LissajousOptions options;
  options.duration_s = 2.0;
  Trajectory samples = makeLissajousTrajectory(options);
  EXPECT_THROW(Se3Spline::fit(samples, 0), OptionError);
  EXPECT_THROW(Se3Spline::fit(samples, 3 * kNsPerSecond), OptionError);  // Longer than the data.
  EXPECT_THROW(Se3Spline::fit(Trajectory(samples.begin(), samples.begin() + 1), kKnotNs),
               InputError);
  Trajectory with_gap = samples;
  for (std::size_t k = with_gap.size() / 2; k < with_gap.size(); ++k) {
    with_gap[k].t_ns += 5 * kNsPerSecond;
  }
  EXPECT_THROW(Se3Spline::fit(with_gap, kKnotNs), InputError);
  std::swap(samples[3], samples[4]);
  EXPECT_THROW(Se3Spline::fit(samples, kKnotNs), InputError);
}

TEST(Se3SplineFitTest, SplitAtGapsKeepsEverySampleInOrder) {
  Trajectory t;
  for (const TimeNs time : {0, 10, 20, 100, 110, 500}) {
    t.push_back({time, SE3d()});
  }
  const std::vector<Trajectory> parts = splitAtGaps(t, 50);
  ASSERT_EQ(parts.size(), 3u);
  EXPECT_EQ(parts[0].size(), 3u);
  EXPECT_EQ(parts[1].front().t_ns, 100);
  EXPECT_EQ(parts[2].front().t_ns, 500);
  EXPECT_TRUE(splitAtGaps({}, 50).empty());
}

}  // namespace
}  // namespace superdyna::sim

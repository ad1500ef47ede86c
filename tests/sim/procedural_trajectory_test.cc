#include "superdyna/sim/procedural_trajectory.h"

#include <gtest/gtest.h>

#include "superdyna/core/error.h"

namespace superdyna::sim {
namespace {

TEST(ProceduralTrajectoryTest, SamplesAtTheRequestedRateAndFacesTheDirectionOfTravel) {
  LissajousOptions options;
  options.duration_s = 10.0;
  options.rate_hz = 20.0;
  options.tilt_rad = 0.0;
  const Trajectory t = makeLissajousTrajectory(options);
  ASSERT_EQ(t.size(), 201u);
  EXPECT_EQ(t[1].t_ns - t[0].t_ns, 50'000'000);
  EXPECT_EQ(t.back().t_ns - t.front().t_ns, 10'000'000'000);
  for (std::size_t i = 1; i + 1 < t.size(); i += 17) {
    const Eigen::Vector3d v = t[i + 1].T_w_x.t - t[i - 1].T_w_x.t;
    const Eigen::Vector3d heading = t[i].T_w_x.rotation().col(0);
    // With zero tilt the body x axis is the horizontal direction of travel.
    EXPECT_GT(heading.dot(Eigen::Vector3d(v.x(), v.y(), 0.0).normalized()), 0.999) << i;
  }
  EXPECT_NEAR(t[0].T_w_x.t.z(), options.height_m, 1e-12);
}

TEST(ProceduralTrajectoryTest, ErrorFreeEstimateIsTheTruthInTheOffsetFrame) {
  const Trajectory truth = makeLissajousTrajectory({});
  EstimateErrorOptions errors;
  errors.position_noise_m = errors.rotation_noise_rad = 0.0;
  errors.drift_m_per_sqrt_s = errors.yaw_drift_rad_per_sqrt_s = 0.0;
  errors.world_offset.s = 2.0;
  errors.world_offset.R = expSO3(Eigen::Vector3d(0.1, 0.2, 0.3));
  errors.world_offset.t = Eigen::Vector3d(1.0, -1.0, 0.5);
  const Trajectory estimate = simulateEstimate(truth, errors);
  ASSERT_EQ(estimate.size(), truth.size());
  for (std::size_t i = 0; i < truth.size(); i += 50) {
    EXPECT_EQ(estimate[i].t_ns, truth[i].t_ns);
    EXPECT_LT((estimate[i].T_w_x.t - errors.world_offset * truth[i].T_w_x.t).norm(), 1e-12);
  }
}

TEST(ProceduralTrajectoryTest, EstimateIsDeterministicForASeedAndDiffersAcrossSeeds) {
  const Trajectory truth = makeLissajousTrajectory({});
  EstimateErrorOptions errors;
  const Trajectory a = simulateEstimate(truth, errors);
  const Trajectory b = simulateEstimate(truth, errors);
  errors.seed = 2;
  const Trajectory c = simulateEstimate(truth, errors);
  EXPECT_EQ(a.back().T_w_x.t, b.back().T_w_x.t);
  EXPECT_NE(a.back().T_w_x.t, c.back().T_w_x.t);
  // Drift of 1 cm/sqrt(s) over 60 s: about 8 cm per axis at the end, never metres.
  EXPECT_LT((a.back().T_w_x.t - truth.back().T_w_x.t).norm(), 0.5);
}

TEST(ProceduralTrajectoryTest, RejectsInvalidOptions) {
  LissajousOptions options;
  options.rate_hz = 0.0;
  EXPECT_THROW(makeLissajousTrajectory(options), OptionError);
  EstimateErrorOptions errors;
  errors.scale = -1.0;
  EXPECT_THROW(simulateEstimate(makeLissajousTrajectory({}), errors), OptionError);
}

}  // namespace
}  // namespace superdyna::sim

#include "superdyna/sim/agents.h"

#include <gtest/gtest.h>

namespace superdyna::sim {
namespace {

LinearMotion pausingWalk() {
  LinearMotion motion;
  motion.start_xy = Eigen::Vector2d(1.0, 2.0);
  motion.heading_rad = 0.5;
  motion.speed_mps = 1.5;
  motion.t_begin_ns = 10 * kNsPerSecond;
  motion.t_end_ns = 20 * kNsPerSecond;
  motion.pause_begin_ns = 14 * kNsPerSecond;
  motion.pause_duration_s = 2.0;
  return motion;
}

TEST(AgentsTest, PausingAgentStandsStillAndCoversTheExpectedDistance) {
  const LinearMotion motion = pausingWalk();
  EXPECT_DOUBLE_EQ(motion.speedAt(12 * kNsPerSecond), 1.5);
  EXPECT_DOUBLE_EQ(motion.speedAt(15 * kNsPerSecond), 0.0);
  EXPECT_DOUBLE_EQ(motion.distanceAt(14'500'000'000), motion.distanceAt(15'900'000'000));
  // 10 s of life, 2 s standing, two 0.5 s ramps that each cover half their cruise distance.
  EXPECT_NEAR(motion.distanceAt(motion.t_end_ns), 1.5 * (10.0 - 2.0 - 0.5), 1e-9);
  const Eigen::Vector2d end = motion.positionAt(motion.t_end_ns);
  EXPECT_NEAR((end - motion.start_xy).norm(), 11.25, 1e-9);
  EXPECT_NEAR(std::atan2(end.y() - 2.0, end.x() - 1.0), 0.5, 1e-12);
}

TEST(AgentsTest, SpeedIsTheDerivativeOfDistanceEverywhere) {
  const LinearMotion motion = pausingWalk();
  constexpr TimeNs kStep = 1'000'000;  // 1 ms
  for (TimeNs t = motion.t_begin_ns + kStep; t < motion.t_end_ns - kStep; t += 37 * kStep) {
    const double numeric = (motion.distanceAt(t + kStep) - motion.distanceAt(t - kStep)) / 2e-3;
    EXPECT_NEAR(numeric, motion.speedAt(t), 1e-4) << nsToSeconds(t);
  }
}

TEST(AgentsTest, AgentExistsOnlyDuringItsLifeAndReportsMotion) {
  const SceneObject agent =
      makeAgent(7, ObjectClass::kPedestrian, pedestrianSize(), 0, pausingWalk());
  EXPECT_EQ(agent.instance_id, 7);
  EXPECT_EQ(agent.quads.size(), 5u);
  EXPECT_FALSE(agent.T_w_o(9 * kNsPerSecond));
  EXPECT_FALSE(agent.T_w_o(21 * kNsPerSecond));
  ASSERT_TRUE(agent.T_w_o(12 * kNsPerSecond));
  EXPECT_TRUE(agent.is_moving(12 * kNsPerSecond));
  EXPECT_FALSE(agent.is_moving(15 * kNsPerSecond));
  // Heading 0.5 rad: the agent's x axis points along its path.
  const SE3d pose = *agent.T_w_o(12 * kNsPerSecond);
  EXPECT_NEAR(pose.rotation().col(0).x(), std::cos(0.5), 1e-12);
}

TEST(AgentsTest, BoxQuadsSpanTheBoxWithSidesStartingAtTheTop) {
  const AgentSize size = vehicleSize();
  const auto quads = makeBoxQuads(size, 3);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (const Quad& q : quads) {
    EXPECT_EQ(q.texture, 3);
    for (double a : {0.0, 1.0}) {
      for (double b : {0.0, 1.0}) {
        const Eigen::Vector3d corner = q.origin + a * q.edge_u + b * q.edge_v;
        lo = lo.cwiseMin(corner);
        hi = hi.cwiseMax(corner);
      }
    }
  }
  EXPECT_LT((lo - Eigen::Vector3d(-2.25, -0.9, 0.0)).norm(), 1e-12);
  EXPECT_LT((hi - Eigen::Vector3d(2.25, 0.9, 1.5)).norm(), 1e-12);
  for (int side = 0; side < 4; ++side)
    EXPECT_LT(quads[side].edge_v.z(), 0.0);
}

}  // namespace
}  // namespace superdyna::sim

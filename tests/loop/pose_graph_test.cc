#include "superdyna/loop/pose_graph.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace superdyna::loop {
namespace {

/// A loop of poses around a circle of 5 m (slightly tilted bodies, facing along the path), the
/// same loop drifted as visual-inertial odometry drifts (world yaw and position growing along
/// it), and the graph's edges: odometry from the drifted poses, plus one loop edge with the
/// true relative pose of the last and the first keyframe.
struct DriftedLoop {
  std::map<map::KeyFrameId, SE3d> truth;
  std::map<map::KeyFrameId, SE3d> drifted;
  std::vector<PoseGraphEdge> edges;
  map::KeyFrameId last = 0;
};

DriftedLoop driftedLoop(int n) {
  DriftedLoop loop;
  const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(0.04, Eigen::Vector3d::UnitX()) *
                                Eigen::AngleAxisd(-0.03, Eigen::Vector3d::UnitY()))
                                   .toRotationMatrix();
  for (int i = 0; i < n; ++i) {
    const double theta = 2.0 * M_PI * i / n;
    const SE3d T(yawRotation(theta + M_PI / 2) * tilt,
                 Eigen::Vector3d(5.0 * std::cos(theta), 5.0 * std::sin(theta), 1.0));
    const double s = static_cast<double>(i) / (n - 1);
    const SE3d drift(yawRotation(0.15 * s), Eigen::Vector3d(0.6 * s, -0.4 * s, 0.1 * s));
    loop.truth[i] = T;
    loop.drifted[i] = drift * T;
  }
  for (int i = 1; i < n; ++i)
    loop.edges.push_back(edgeBetween(i - 1, loop.drifted[i - 1], i, loop.drifted[i]));
  loop.last = n - 1;
  loop.edges.push_back(edgeBetween(0, loop.truth[0], loop.last, loop.truth[loop.last]));
  return loop;
}

double positionError(const std::map<map::KeyFrameId, SE3d>& poses, const DriftedLoop& loop,
                     map::KeyFrameId id) {
  return (poses.at(id).t - loop.truth.at(id).t).norm();
}

double maxPositionError(const std::map<map::KeyFrameId, SE3d>& poses, const DriftedLoop& loop) {
  double worst = 0.0;
  for (const auto& [id, T] : poses)
    worst = std::max(worst, positionError(poses, loop, id));
  return worst;
}

void expectClosedAndDistributed(const PoseGraphResult& result, const DriftedLoop& loop) {
  const double end_before = positionError(loop.drifted, loop, loop.last);
  const double end_after = positionError(result.T_w_b, loop, loop.last);
  EXPECT_GT(end_before, 0.7);  // the drift to be corrected
  EXPECT_LT(end_after, 0.1 * end_before);
  // The error is spread over the loop: no pose as far off as the drifted end, none at the start.
  EXPECT_LT(maxPositionError(result.T_w_b, loop), 0.5 * maxPositionError(loop.drifted, loop));
  EXPECT_LT(positionError(result.T_w_b, loop, 0), 1e-9);  // held
  EXPECT_LT(result.final_cost, 0.1 * result.initial_cost);
}

TEST(PoseGraph, FourDofClosesADriftedLoopKeepingRollAndPitch) {
  const DriftedLoop loop = driftedLoop(40);
  PoseGraphOptions options;
  options.four_dof = true;
  const PoseGraphResult result = optimizePoseGraph(loop.drifted, loop.edges, {0}, options);
  expectClosedAndDistributed(result, loop);
  // Gravity's directions stay: only yaw and position moved.
  for (const auto& [id, T] : result.T_w_b) {
    const Eigen::Vector3d up = T.rotation().transpose() * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d up0 =
        loop.drifted.at(id).rotation().transpose() * Eigen::Vector3d::UnitZ();
    EXPECT_LT((up - up0).norm(), 1e-9) << "keyframe " << id;
  }
  // The yaw drift is gone at the end.
  const Eigen::Matrix3d R_error =
      result.T_w_b.at(loop.last).rotation() * loop.truth.at(loop.last).rotation().transpose();
  EXPECT_LT(rotationAngle(R_error), 0.01);
}

TEST(PoseGraph, SixDofClosesADriftedLoop) {
  const DriftedLoop loop = driftedLoop(40);
  const PoseGraphResult result = optimizePoseGraph(loop.drifted, loop.edges, {0});
  expectClosedAndDistributed(result, loop);
}

/// The loop of driftedLoop as monocular odometry drifts: each step's length shrinks (scale
/// drift, to 0.67 of the truth at the end) and the heading turns a little; the loop edge measures
/// the true similarity between the first and the last keyframe's frames.
DriftedLoop scaleDriftedLoop(int n, double& end_scale) {
  DriftedLoop loop = driftedLoop(n);
  loop.edges.clear();
  SE3d drifted = loop.truth.at(0);
  loop.drifted[0] = drifted;
  double f = 1.0;
  for (int i = 1; i < n; ++i) {
    f = std::exp(-0.4 * i / (n - 1));
    SE3d step = loop.truth.at(i - 1).inverse() * loop.truth.at(i);
    step.t *= f;
    drifted = drifted * SE3d(yawRotation(0.004), Eigen::Vector3d::Zero()) * step;
    loop.drifted[i] = drifted;
    loop.edges.push_back(edgeBetween(i - 1, loop.drifted[i - 1], i, loop.drifted[i]));
  }
  end_scale = 1.0 / f;  // a unit length of the last keyframe's frame in the world
  loop.edges.push_back(
      edgeBetween(0, loop.truth.at(0), 1.0, loop.last, loop.truth.at(loop.last), end_scale));
  return loop;
}

TEST(PoseGraph, SevenDofClosesALoopThatDriftedInScale) {
  double end_scale = 0.0;
  const DriftedLoop loop = scaleDriftedLoop(40, end_scale);
  PoseGraphOptions options;
  options.seven_dof = true;
  const PoseGraphResult result = optimizePoseGraph(loop.drifted, loop.edges, {0}, options);
  expectClosedAndDistributed(result, loop);
  EXPECT_NEAR(result.scale.at(loop.last), end_scale, 0.01 * end_scale);
  EXPECT_EQ(result.scale.at(0), 1.0);  // held
  // Scales grow along the loop, as the drift shrank the steps.
  EXPECT_GT(result.scale.at(20), 1.1);
  EXPECT_LT(result.scale.at(20), result.scale.at(loop.last));
  // Six DoF cannot undo the shrunken steps: its end stays further off.
  const PoseGraphResult rigid = optimizePoseGraph(loop.drifted, loop.edges, {0});
  EXPECT_GT(maxPositionError(rigid.T_w_b, loop), 2.0 * maxPositionError(result.T_w_b, loop));
}

TEST(PoseGraph, WithoutTheLoopEdgeNothingMoves) {
  DriftedLoop loop = driftedLoop(20);
  loop.edges.pop_back();
  const PoseGraphResult result = optimizePoseGraph(loop.drifted, loop.edges, {0});
  for (const auto& [id, T] : result.T_w_b)
    EXPECT_LT((T.t - loop.drifted.at(id).t).norm(), 1e-6);
}

TEST(PoseGraph, RejectsEdgesToUnknownKeyFrames) {
  const DriftedLoop loop = driftedLoop(5);
  std::vector<PoseGraphEdge> edges = loop.edges;
  edges.push_back({0, 99, SE3d()});
  EXPECT_THROW(optimizePoseGraph(loop.drifted, edges, {0}), std::invalid_argument);
}

}  // namespace
}  // namespace superdyna::loop

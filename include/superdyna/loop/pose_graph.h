#pragma once
// Pose-graph optimisation of keyframe body poses (Ceres): relative-pose edges between keyframes
// pull the poses towards their measured relative poses.
//
// Six degrees of freedom (visual stereo maps): each pose is free; an edge i -> j measuring
// T_i_j has the residual [w_r * 2 vec(q_ij^-1 q_i^-1 q_j); R_i^T (t_j - t_i) - t_ij].
// Four (inertial maps, ORB-SLAM3's 4-DoF graph): gravity fixes roll and pitch, so each pose keeps
// its initial roll and pitch and only its yaw about the world z axis (up) and its position move:
// R_i = Rz(d_i) R_i0. The edge's yaw residual is w_r ((d_j - d_i) - yaw(R_i0 R_ij R_j0^T)) and its
// translation residual as above.
// Seven (monocular maps, Sim(3) as ORB-SLAM's essential graph): each keyframe also has a scale
// s_i = exp(sigma_i), the length in the world of a unit length of its own frame; an edge measures
// the similarity between the two frames, R_ij, t_ij = R_i^T (t_j - t_i) / s_i and
// sigma_ij = sigma_j - sigma_i, with the rotation residual above, the translation residual
// R_i^T (t_j - t_i) exp(-sigma_i) - t_ij and the scale residual (sigma_j - sigma_i) - sigma_ij.
//
// The fixed keyframes hold the gauge. Squared loss: the edges are trusted (verified loops,
// odometry of the map).

#include <map>
#include <set>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/map/map_point.h"

namespace superdyna::loop {

struct PoseGraphEdge {
  map::KeyFrameId from = map::kNoKeyFrame;
  map::KeyFrameId to = map::kNoKeyFrame;
  SE3d T_from_to;  ///< Measured relative pose: T_w_from^-1 * T_w_to (position in from's scale).
  double log_scale = 0.0;  ///< Seven-DoF: measured log(s_to / s_from).
};

struct PoseGraphOptions {
  bool four_dof = false;         ///< Yaw + position (inertial maps); else full SE(3) ...
  bool seven_dof = false;        ///< ... or Sim(3): pose and scale (monocular maps).
  int iterations = 20;           ///< Levenberg-Marquardt iterations, >= 1.
  double rotation_weight = 1.0;  ///< Residual units of 1 rad against 1 m, > 0 (ORB-SLAM: 1).
  /// Throws OptionError naming the first invalid field (prefix "loop.pose_graph_").
  void validate() const;
  bool operator==(const PoseGraphOptions&) const = default;
};

struct PoseGraphResult {
  std::map<map::KeyFrameId, SE3d> T_w_b;    ///< Optimised poses of every node.
  std::map<map::KeyFrameId, double> scale;  ///< ... and scales (1 unless seven_dof).
  double initial_cost = 0.0;
  double final_cost = 0.0;
  int iterations = 0;
};

/// The edge measuring the relative pose of two given poses.
PoseGraphEdge edgeBetween(map::KeyFrameId from, const SE3d& T_w_from, map::KeyFrameId to,
                          const SE3d& T_w_to);
/// The seven-DoF edge measuring the relative similarity of two given poses with scales.
PoseGraphEdge edgeBetween(map::KeyFrameId from, const SE3d& T_w_from, double s_from,
                          map::KeyFrameId to, const SE3d& T_w_to, double s_to);

/// Optimises the poses of `initial` (all nodes) under `edges` (whose ends must be nodes, else
/// std::invalid_argument), holding `fixed` ones constant. Seven-DoF: a node's initial scale is
/// its entry in `initial_scale`, else 1.
PoseGraphResult optimizePoseGraph(const std::map<map::KeyFrameId, SE3d>& initial,
                                  const std::vector<PoseGraphEdge>& edges,
                                  const std::set<map::KeyFrameId>& fixed,
                                  const PoseGraphOptions& options = {},
                                  const std::map<map::KeyFrameId, double>& initial_scale = {});

/// Rotation about the world z axis by `yaw` [rad].
Eigen::Matrix3d yawRotation(double yaw);
/// The yaw [rad] of a rotation's x axis about the world z axis (exact for rotations about z).
double yawOf(const Eigen::Matrix3d& R);

}  // namespace superdyna::loop

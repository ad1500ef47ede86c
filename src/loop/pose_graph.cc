#include "superdyna/loop/pose_graph.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <cmath>
#include <stdexcept>

#include "superdyna/core/error.h"
#include "superdyna/optim/solver_options.h"

namespace superdyna::loop {

void PoseGraphOptions::validate() const {
  if (iterations < 1) throw OptionError("loop.pose_graph_iterations", "must be >= 1");
  if (!(rotation_weight > 0.0)) throw OptionError("loop.pose_graph_rotation_weight", "must be > 0");
  if (four_dof && seven_dof)
    throw std::invalid_argument("a pose graph is 4-DoF or 7-DoF, not both");
}

Eigen::Matrix3d yawRotation(double yaw) {
  return Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

double yawOf(const Eigen::Matrix3d& R) {
  return std::atan2(R(1, 0), R(0, 0));
}

PoseGraphEdge edgeBetween(map::KeyFrameId from, const SE3d& T_w_from, map::KeyFrameId to,
                          const SE3d& T_w_to) {
  return {from, to, T_w_from.inverse() * T_w_to};
}

PoseGraphEdge edgeBetween(map::KeyFrameId from, const SE3d& T_w_from, double s_from,
                          map::KeyFrameId to, const SE3d& T_w_to, double s_to) {
  PoseGraphEdge edge = edgeBetween(from, T_w_from, to, T_w_to);
  edge.T_from_to.t /= s_from;
  edge.log_scale = std::log(s_to / s_from);
  return edge;
}

namespace {

/// The rotation and translation residuals of a relative pose edge (6 values): node poses
/// (q_i, t_i), (q_j, t_j), the position of j seen from i multiplied by `inverse_scale_i`.
template <typename T>
void relativePoseResidual(const T* qi_raw, const T* ti_raw, const T* qj_raw, const T* tj_raw,
                          const T& inverse_scale_i, const Eigen::Quaterniond& q_ij,
                          const Eigen::Vector3d& t_ij, double w, T* residual) {
  const Eigen::Map<const Eigen::Quaternion<T>> qi(qi_raw);
  const Eigen::Map<const Eigen::Matrix<T, 3, 1>> ti(ti_raw);
  const Eigen::Map<const Eigen::Quaternion<T>> qj(qj_raw);
  const Eigen::Map<const Eigen::Matrix<T, 3, 1>> tj(tj_raw);
  const Eigen::Quaternion<T> qi_inv = qi.conjugate();
  const Eigen::Quaternion<T> error = q_ij.cast<T>().conjugate() * (qi_inv * qj);
  const Eigen::Matrix<T, 3, 1> t_pred = (qi_inv * (tj - ti)) * inverse_scale_i;
  const T sign = error.w() < T(0) ? T(-1) : T(1);  // the shorter of the two rotations
  for (int k = 0; k < 3; ++k) {
    residual[k] = T(2.0 * w) * sign * error.vec()(k);
    residual[3 + k] = t_pred(k) - T(t_ij(k));
  }
}

/// Six-DoF relative pose residual; parameters q_i (x, y, z, w), t_i, q_j, t_j.
struct RelativePoseError {
  RelativePoseError(const SE3d& T_ij, double rotation_weight)
      : q_ij(T_ij.q), t_ij(T_ij.t), w(rotation_weight) {}

  template <typename T>
  bool operator()(const T* qi_raw, const T* ti_raw, const T* qj_raw, const T* tj_raw,
                  T* residual) const {
    relativePoseResidual(qi_raw, ti_raw, qj_raw, tj_raw, T(1.0), q_ij, t_ij, w, residual);
    return true;
  }

  Eigen::Quaterniond q_ij;
  Eigen::Vector3d t_ij;
  double w;
};

/// Seven-DoF relative similarity residual; parameters q_i, t_i, sigma_i, q_j, t_j, sigma_j.
struct RelativeSimilarityError {
  RelativeSimilarityError(const PoseGraphEdge& edge, double rotation_weight)
      : q_ij(edge.T_from_to.q),
        t_ij(edge.T_from_to.t),
        sigma_ij(edge.log_scale),
        w(rotation_weight) {}

  template <typename T>
  bool operator()(const T* qi_raw, const T* ti_raw, const T* sigma_i, const T* qj_raw,
                  const T* tj_raw, const T* sigma_j, T* residual) const {
    relativePoseResidual(qi_raw, ti_raw, qj_raw, tj_raw, exp(-sigma_i[0]), q_ij, t_ij, w, residual);
    residual[6] = (sigma_j[0] - sigma_i[0]) - T(sigma_ij);
    return true;
  }

  Eigen::Quaterniond q_ij;
  Eigen::Vector3d t_ij;
  double sigma_ij;
  double w;
};

/// Four-DoF residual: yaw offsets d_i, d_j about world z of fixed initial rotations, positions.
struct YawPositionError {
  YawPositionError(const Eigen::Matrix3d& R_from, double yaw_from_to,
                   const Eigen::Vector3d& t_from_to, double rotation_weight)
      : R_i0(R_from), yaw_ij(yaw_from_to), t_ij(t_from_to), w(rotation_weight) {}

  template <typename T>
  bool operator()(const T* di, const T* ti_raw, const T* dj, const T* tj_raw, T* residual) const {
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> ti(ti_raw);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> tj(tj_raw);
    const T c = cos(di[0]);
    const T s = sin(di[0]);
    Eigen::Matrix<T, 3, 3> Rz;
    Rz << c, -s, T(0), s, c, T(0), T(0), T(0), T(1);
    const Eigen::Matrix<T, 3, 3> R_i = Rz * R_i0.cast<T>();
    const Eigen::Matrix<T, 3, 1> t_pred = R_i.transpose() * (tj - ti);
    T yaw_error = (dj[0] - di[0]) - T(yaw_ij);
    yaw_error = atan2(sin(yaw_error), cos(yaw_error));  // wrapped to (-pi, pi]
    residual[0] = T(w) * yaw_error;
    for (int k = 0; k < 3; ++k)
      residual[1 + k] = t_pred(k) - T(t_ij(k));
    return true;
  }

  Eigen::Matrix3d R_i0;
  double yaw_ij;
  Eigen::Vector3d t_ij;
  double w;
};

struct Node {
  Eigen::Quaterniond q;  ///< Six-DoF: the rotation; four-DoF: the initial one (held).
  Eigen::Vector3d t;
  double yaw = 0.0;    ///< Four-DoF: offset about world z from the initial rotation.
  double sigma = 0.0;  ///< Seven-DoF: log of the scale.
};

void setQuaternionManifold(ceres::Problem& problem, Node& node) {
  if (!problem.HasManifold(node.q.coeffs().data()))
    problem.SetManifold(node.q.coeffs().data(), new ceres::EigenQuaternionManifold());
}

void solve(ceres::Problem& problem, const PoseGraphOptions& options, PoseGraphResult& result) {
  const ceres::Solver::Options solver =
      optim::quietSolverOptions(ceres::SPARSE_NORMAL_CHOLESKY, options.iterations);
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.iterations = static_cast<int>(summary.iterations.size());
}

}  // namespace

PoseGraphResult optimizePoseGraph(const std::map<map::KeyFrameId, SE3d>& initial,
                                  const std::vector<PoseGraphEdge>& edges,
                                  const std::set<map::KeyFrameId>& fixed,
                                  const PoseGraphOptions& options,
                                  const std::map<map::KeyFrameId, double>& initial_scale) {
  options.validate();
  std::map<map::KeyFrameId, Node> nodes;
  for (const auto& [id, T] : initial) {
    const auto scale = initial_scale.find(id);
    nodes[id] = {T.q.normalized(), T.t, 0.0,
                 scale == initial_scale.end() ? 0.0 : std::log(scale->second)};
  }
  ceres::Problem problem;
  for (const PoseGraphEdge& edge : edges) {
    const auto from = nodes.find(edge.from);
    const auto to = nodes.find(edge.to);
    if (from == nodes.end() || to == nodes.end()) {
      throw std::invalid_argument("optimizePoseGraph: edge " + std::to_string(edge.from) + " -> " +
                                  std::to_string(edge.to) + " names a keyframe that is no node");
    }
    Node& i = from->second;
    Node& j = to->second;
    if (options.four_dof) {
      const Eigen::Matrix3d R_i0 = i.q.toRotationMatrix();
      const double yaw_ij =
          yawOf(R_i0 * edge.T_from_to.rotation() * j.q.toRotationMatrix().transpose());
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<YawPositionError, 4, 1, 3, 1, 3>(
              new YawPositionError(R_i0, yaw_ij, edge.T_from_to.t, options.rotation_weight)),
          nullptr, &i.yaw, i.t.data(), &j.yaw, j.t.data());
    } else if (options.seven_dof) {
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<RelativeSimilarityError, 7, 4, 3, 1, 4, 3, 1>(
              new RelativeSimilarityError(edge, options.rotation_weight)),
          nullptr, i.q.coeffs().data(), i.t.data(), &i.sigma, j.q.coeffs().data(), j.t.data(),
          &j.sigma);
      setQuaternionManifold(problem, i);
      setQuaternionManifold(problem, j);
    } else {
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<RelativePoseError, 6, 4, 3, 4, 3>(
                                   new RelativePoseError(edge.T_from_to, options.rotation_weight)),
                               nullptr, i.q.coeffs().data(), i.t.data(), j.q.coeffs().data(),
                               j.t.data());
      setQuaternionManifold(problem, i);
      setQuaternionManifold(problem, j);
    }
  }
  for (const map::KeyFrameId id : fixed) {
    const auto node = nodes.find(id);
    if (node == nodes.end()) continue;
    if (options.four_dof) {
      if (problem.HasParameterBlock(&node->second.yaw)) {
        problem.SetParameterBlockConstant(&node->second.yaw);
      }
    } else if (problem.HasParameterBlock(node->second.q.coeffs().data())) {
      problem.SetParameterBlockConstant(node->second.q.coeffs().data());
    }
    if (problem.HasParameterBlock(node->second.t.data())) {
      problem.SetParameterBlockConstant(node->second.t.data());
    }
    if (problem.HasParameterBlock(&node->second.sigma)) {
      problem.SetParameterBlockConstant(&node->second.sigma);
    }
  }
  PoseGraphResult result;
  if (problem.NumResidualBlocks() > 0) solve(problem, options, result);
  for (const auto& [id, node] : nodes) {
    const Eigen::Quaterniond q =
        options.four_dof ? Eigen::Quaterniond(yawRotation(node.yaw) * node.q.toRotationMatrix())
                         : node.q.normalized();
    result.T_w_b[id] = SE3d(q, node.t);
    result.scale[id] = std::exp(node.sigma);
  }
  return result;
}

}  // namespace superdyna::loop

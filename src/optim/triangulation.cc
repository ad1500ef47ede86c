#include "superdyna/optim/triangulation.h"

#include <Eigen/SVD>
#include <cmath>

#include "superdyna/core/error.h"

namespace superdyna::optim {

namespace {

/// Rows of b x (P X) = 0 for one view with P = [R | t] (3x4): rank 2, all three kept so that no
/// component of the bearing needs to be non-zero.
Eigen::Matrix<double, 3, 4> crossProductRows(const Eigen::Vector3d& bearing,
                                             const Eigen::Matrix<double, 3, 4>& P) {
  return hat(bearing.normalized()) * P;
}

TriangulationResult withStatus(TriangulationStatus status, double cos_parallax) {
  TriangulationResult result;
  result.status = status;
  result.cos_parallax = cos_parallax;
  return result;
}

}  // namespace

void TriangulationOptions::validate() const {
  if (!(max_cos_parallax > -1.0 && max_cos_parallax <= 1.0)) {
    throw OptionError("triangulation.max_cos_parallax", "must be in (-1, 1]");
  }
  if (!(min_depth_m >= 0.0) || !std::isfinite(min_depth_m)) {
    throw OptionError("triangulation.min_depth_m", "must be a finite number >= 0");
  }
}

std::string toString(TriangulationStatus status) {
  switch (status) {
    case TriangulationStatus::kOk:
      return "ok";
    case TriangulationStatus::kLowParallax:
      return "low parallax";
    case TriangulationStatus::kBehindCamera:
      return "behind camera";
    case TriangulationStatus::kDegenerate:
      return "degenerate";
  }
  return "unknown";
}

double cosParallax(const Eigen::Vector3d& bearing_c1, const SE3d& T_w_c1,
                   const Eigen::Vector3d& bearing_c2, const SE3d& T_w_c2) {
  const Eigen::Vector3d ray1_w = T_w_c1.q * bearing_c1.normalized();
  const Eigen::Vector3d ray2_w = T_w_c2.q * bearing_c2.normalized();
  return ray1_w.dot(ray2_w);
}

TriangulationResult triangulateTwoView(const Eigen::Vector3d& bearing_c1, const SE3d& T_w_c1,
                                       const Eigen::Vector3d& bearing_c2, const SE3d& T_w_c2,
                                       const TriangulationOptions& options) {
  options.validate();
  if (!(bearing_c1.norm() > 0.0) || !(bearing_c2.norm() > 0.0)) {
    return withStatus(TriangulationStatus::kDegenerate, 1.0);
  }
  const double cos_parallax = cosParallax(bearing_c1, T_w_c1, bearing_c2, T_w_c2);
  if (cos_parallax > options.max_cos_parallax) {
    return withStatus(TriangulationStatus::kLowParallax, cos_parallax);
  }

  // Solved in camera 1's frame (P1 = [I | 0]) so that large world coordinates do not degrade the
  // conditioning of the system.
  const SE3d T_c2_c1 = T_w_c2.inverse() * T_w_c1;
  Eigen::Matrix<double, 6, 4> A;
  A.topRows<3>() = crossProductRows(bearing_c1, Eigen::Matrix<double, 3, 4>::Identity());
  A.bottomRows<3>() = crossProductRows(bearing_c2, T_c2_c1.matrix3x4());
  const Eigen::JacobiSVD<Eigen::Matrix<double, 6, 4>> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d X = svd.matrixV().col(3);
  if (std::abs(X(3)) < 1e-12 * X.head<3>().norm() || !X.allFinite()) {
    return withStatus(TriangulationStatus::kDegenerate, cos_parallax);
  }
  const Eigen::Vector3d p_c1 = X.head<3>() / X(3);
  TriangulationResult result = withStatus(TriangulationStatus::kOk, cos_parallax);
  result.p_w = T_w_c1 * p_c1;

  const double depth1 = bearing_c1.normalized().dot(p_c1);
  const double depth2 = bearing_c2.normalized().dot(T_c2_c1 * p_c1);
  if (!(depth1 > options.min_depth_m) || !(depth2 > options.min_depth_m)) {
    result.status = TriangulationStatus::kBehindCamera;
  }
  return result;
}

std::optional<Eigen::Vector3d> pointFromDepth(const Eigen::Vector2d& normalized, double depth_m,
                                              const SE3d& T_w_c) {
  if (!(depth_m > 0.0) || !std::isfinite(depth_m)) return std::nullopt;
  const Eigen::Vector3d p_c = depth_m * normalized.homogeneous();
  return T_w_c * p_c;
}

std::optional<double> depthFromRectifiedStereo(double x_left, double x_right, double baseline_m) {
  const double disparity = x_left - x_right;
  if (!(disparity > 0.0) || !(baseline_m > 0.0)) return std::nullopt;
  return baseline_m / disparity;
}

}  // namespace superdyna::optim

#include "superdyna/dynamic/motion_residual.h"

#include <cmath>

namespace superdyna::dynamic {

namespace {

/// Normalised image point of a camera-frame direction; nullopt behind (or at) the camera.
std::optional<Eigen::Vector2d> normalizedOf(const Eigen::Vector3d& p) {
  if (!(p.z() > 1e-9)) return std::nullopt;
  return Eigen::Vector2d(p.x() / p.z(), p.y() / p.z());
}

}  // namespace

const char* toString(ResidualTest test) {
  switch (test) {
    case ResidualTest::kEpipolar:
      return "epipolar";
    case ResidualTest::kReprojection:
      return "reprojection";
    case ResidualTest::kRotationTransfer:
      return "rotation";
  }
  return "?";
}

std::optional<double> epipolarDistancePx(const Eigen::Vector2d& x_prev,
                                         const Eigen::Vector2d& x_cur, const SE3d& T_cur_prev,
                                         double focal_px) {
  if (!(T_cur_prev.t.norm() > 0.0)) return std::nullopt;
  // x_cur^T E x_prev = 0 for a static point, E = [t]x R (T_cur_prev maps previous-camera points
  // into the current camera).
  const Eigen::Matrix3d E = hat(T_cur_prev.t) * T_cur_prev.rotation();
  const Eigen::Vector3d line = E * x_prev.homogeneous();
  const double norm = line.head<2>().norm();
  if (!(norm > 1e-12)) return std::nullopt;
  return focal_px * std::abs(line.dot(x_cur.homogeneous())) / norm;
}

std::optional<double> epipolarRayDistancePx(const Eigen::Vector2d& x_prev,
                                            const Eigen::Vector2d& x_cur, const SE3d& T_cur_prev,
                                            double focal_px) {
  const std::optional<double> line_distance =
      epipolarDistancePx(x_prev, x_cur, T_cur_prev, focal_px);
  if (!line_distance) return std::nullopt;
  // A static point at depth d along the previous ray is seen at d a + t (up to scale).
  const Eigen::Vector3d a = T_cur_prev.q * x_prev.homogeneous();
  const Eigen::Vector3d& t = T_cur_prev.t;
  const Eigen::Vector3d x = x_cur.homogeneous();
  const Eigen::Vector3d x_cross_a = x.cross(a);
  const double denominator = x_cross_a.squaredNorm();
  // At the point at infinite depth, or that point behind the camera: the line test alone.
  if (!(a.z() > 1e-9) || !(denominator > 1e-18)) return line_distance;
  // Least-squares depth of x ~ d a + t: d (x x a) = -(x x t).
  const double depth = -x.cross(t).dot(x_cross_a) / denominator;
  if (depth > 0.0 && (depth * a + t).z() > 0.0) return line_distance;
  double beyond = (x_cur - a.head<2>() / a.z()).norm();
  // Moving backward, the reachable part ends at the epipole (depth 0) on the other side.
  if (t.z() > 1e-12) beyond = std::min(beyond, (x_cur - t.head<2>() / t.z()).norm());
  return std::max(*line_distance, focal_px * beyond);
}

std::optional<double> reprojectionDistancePx(const Eigen::Vector3d& p_prev,
                                             const Eigen::Vector2d& x_cur, const SE3d& T_cur_prev,
                                             double focal_px) {
  const auto predicted = normalizedOf(T_cur_prev * p_prev);
  if (!predicted) return std::nullopt;
  return focal_px * (*predicted - x_cur).norm();
}

std::optional<double> rotationTransferDistancePx(const Eigen::Vector2d& x_prev,
                                                 const Eigen::Vector2d& x_cur,
                                                 const SE3d& T_cur_prev, double focal_px) {
  const auto predicted = normalizedOf(T_cur_prev.q * x_prev.homogeneous());
  if (!predicted) return std::nullopt;
  return focal_px * (*predicted - x_cur).norm();
}

}  // namespace superdyna::dynamic

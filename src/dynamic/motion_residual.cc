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

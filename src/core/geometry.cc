#include "superdyna/core/geometry.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

namespace superdyna {

Eigen::Matrix3d hat(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

Eigen::Matrix3d expSO3(const Eigen::Vector3d& omega) {
  const double theta = omega.norm();
  if (theta < 1e-12) return Eigen::Matrix3d::Identity() + hat(omega);
  return Eigen::AngleAxisd(theta, omega / theta).toRotationMatrix();
}

Eigen::Vector3d logSO3(const Eigen::Matrix3d& R) {
  // Through the quaternion: stable near 0 (atan2 of small numbers) and near pi.
  Eigen::Quaterniond q(R);
  q.normalize();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  const Eigen::Vector3d v = q.vec();
  const double sin_half = v.norm();
  if (sin_half < 1e-12) return 2.0 * v;  // first-order: theta * axis = 2 * sin(theta/2) * axis
  const double theta = 2.0 * std::atan2(sin_half, q.w());
  return v * (theta / sin_half);
}

Eigen::Matrix3d rightJacobianSO3(const Eigen::Vector3d& phi) {
  const double theta2 = phi.squaredNorm();
  const Eigen::Matrix3d Phi = hat(phi);
  double a = 0.0;  // (1 - cos t) / t^2
  double b = 0.0;  // (t - sin t) / t^3
  if (theta2 < 1e-8) {
    a = 0.5 - theta2 / 24.0;
    b = 1.0 / 6.0 - theta2 / 120.0;
  } else {
    const double theta = std::sqrt(theta2);
    a = (1.0 - std::cos(theta)) / theta2;
    b = (theta - std::sin(theta)) / (theta2 * theta);
  }
  return Eigen::Matrix3d::Identity() - a * Phi + b * Phi * Phi;
}

Eigen::Matrix3d rightJacobianInverseSO3(const Eigen::Vector3d& phi) {
  const double theta2 = phi.squaredNorm();
  const Eigen::Matrix3d Phi = hat(phi);
  double c = 0.0;  // 1 / t^2 - (1 + cos t) / (2 t sin t)
  if (theta2 < 1e-8) {
    c = 1.0 / 12.0 + theta2 / 720.0;
  } else {
    const double theta = std::sqrt(theta2);
    c = 1.0 / theta2 - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta));
  }
  return Eigen::Matrix3d::Identity() + 0.5 * Phi + c * Phi * Phi;
}

double rotationAngle(const Eigen::Matrix3d& R) {
  return logSO3(R).norm();
}

Eigen::Matrix3d nearestRotation(const Eigen::Matrix3d& M) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0) D(2, 2) = -1.0;
  return svd.matrixU() * D * svd.matrixV().transpose();
}

SE3d::SE3d(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation)
    : q(rotation.normalized()), t(translation) {}

SE3d::SE3d(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation)
    : q(Eigen::Quaterniond(rotation).normalized()), t(translation) {}

SE3d SE3d::fromMatrix(const Eigen::Matrix<double, 3, 4>& M) {
  return SE3d(nearestRotation(M.leftCols<3>()), M.col(3));
}

SE3d SE3d::fromMatrix(const Eigen::Matrix4d& M) {
  return fromMatrix(Eigen::Matrix<double, 3, 4>(M.topRows<3>()));
}

Eigen::Matrix4d SE3d::matrix() const {
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  M.topLeftCorner<3, 3>() = rotation();
  M.topRightCorner<3, 1>() = t;
  return M;
}

Eigen::Matrix<double, 3, 4> SE3d::matrix3x4() const {
  return matrix().topRows<3>();
}

SE3d SE3d::inverse() const {
  const Eigen::Quaterniond q_inv = q.conjugate();
  return SE3d(q_inv, -(q_inv * t));
}

SE3d SE3d::operator*(const SE3d& other) const {
  return SE3d(q * other.q, q * other.t + t);
}

SE3d Sim3d::operator*(const SE3d& pose) const {
  return SE3d(Eigen::Matrix3d(R * pose.rotation()), (*this) * pose.t);
}

Sim3d Sim3d::inverse() const {
  Sim3d inv;
  inv.s = 1.0 / s;
  inv.R = R.transpose();
  inv.t = -(inv.R * t) / s;
  return inv;
}

}  // namespace superdyna

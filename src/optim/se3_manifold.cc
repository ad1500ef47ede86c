#include "superdyna/optim/se3_manifold.h"

#include <Eigen/Geometry>
#include <algorithm>

namespace superdyna::optim {

PoseBlock toPoseBlock(const SE3d& T_w_b) {
  const Eigen::Quaterniond q = T_w_b.q.normalized();
  return {q.x(), q.y(), q.z(), q.w(), T_w_b.t.x(), T_w_b.t.y(), T_w_b.t.z()};
}

SE3d fromPoseBlock(const double* block) {
  const Eigen::Quaterniond q(block[3], block[0], block[1], block[2]);
  return SE3d(q.normalized(), Eigen::Vector3d(block[4], block[5], block[6]));
}

SE3d plusPose(const SE3d& T_w_b, const Vector6d& delta) {
  // Ceres' quaternion manifold: q <- [sin|dq| dq/|dq|, cos|dq|] q, a rotation by 2 dq.
  const Eigen::Matrix3d R_w_b = expSO3(2.0 * delta.head<3>()) * T_w_b.rotation();
  return SE3d(R_w_b, T_w_b.t + delta.tail<3>());
}

Eigen::Matrix<double, 3, 4> rotationTangentFromQuaternion(const double* q_xyzw) {
  // With q' = Exp(dtheta) q ~= [dtheta / 2; 1] (x) q, dtheta = 2 vec(dq (x) q^-1); for unit
  // q = (v, w), vec(dq (x) q*) = (w I + [v]x) dq_v - v dq_w. Dividing by the norm accounts for the
  // residual normalising q.
  const Eigen::Map<const Eigen::Vector4d> raw(q_xyzw);
  const double norm = raw.norm();
  const Eigen::Vector4d unit = raw / norm;
  const Eigen::Vector3d v = unit.head<3>();
  const double w = unit(3);
  Eigen::Matrix<double, 3, 4> J;
  J.leftCols<3>() = w * Eigen::Matrix3d::Identity() + hat(v);
  J.col(3) = -v;
  return (2.0 / norm) * J;
}

bool RollPitchPoseManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  const double dq[3] = {delta[0], delta[1], 0.0};
  if (!ceres::EigenQuaternionManifold().Plus(x, dq, x_plus_delta)) return false;
  std::copy(x + 4, x + 7, x_plus_delta + 4);
  return true;
}

bool RollPitchPoseManifold::PlusJacobian(const double* x, double* jacobian) const {
  Eigen::Matrix<double, 4, 3, Eigen::RowMajor> J_q;
  if (!ceres::EigenQuaternionManifold().PlusJacobian(x, J_q.data())) return false;
  Eigen::Map<Eigen::Matrix<double, kPoseBlockSize, 2, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  J.topRows<4>() = J_q.leftCols<2>();
  return true;
}

bool RollPitchPoseManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  double dq[3];
  if (!ceres::EigenQuaternionManifold().Minus(y, x, dq)) return false;
  y_minus_x[0] = dq[0];
  y_minus_x[1] = dq[1];
  return true;
}

bool RollPitchPoseManifold::MinusJacobian(const double* x, double* jacobian) const {
  Eigen::Matrix<double, 3, 4, Eigen::RowMajor> J_q;
  if (!ceres::EigenQuaternionManifold().MinusJacobian(x, J_q.data())) return false;
  Eigen::Map<Eigen::Matrix<double, 2, kPoseBlockSize, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  J.leftCols<4>() = J_q.topRows<2>();
  return true;
}

Eigen::Matrix<double, kPoseBlockSize, kPoseTangentSize> posePlusJacobian(const double* block) {
  Eigen::Matrix<double, kPoseBlockSize, kPoseTangentSize, Eigen::RowMajor> J;
  SE3Manifold().PlusJacobian(block, J.data());
  return J;
}

}  // namespace superdyna::optim

#pragma once
// Pose parameter blocks for Ceres (the convention of imu_factors.h, shared by every factor):
//
//   block    7 doubles [qx, qy, qz, qw, px, py, pz] = T_w_b: the unit quaternion of R_w_b in
//            Eigen's (x, y, z, w) order, then the position p_w [m].
//   manifold SE3Manifold = ceres::EigenQuaternionManifold x R^3, tangent delta = [dq (3), dp (3)]:
//            Plus(T, delta) = (Exp(2 dq) R_w_b, p_w + dp), a LEFT (world-frame) rotation update.
//            Note the factor 2: Ceres' quaternion manifold forms the update quaternion
//            [sin|dq| dq/|dq|, cos|dq|], so dq is HALF the rotation vector (PlusJacobian at the
//            identity is [I; 0], not [I/2; 0]). Tangent-space quantities from Ceres (e.g.
//            ceres::Covariance of a pose block) therefore have their rotation part in half-angle
//            units: Cov(dtheta) = 4 Cov(dq).
//
// Factors with analytic Jacobians compute them for the rotation vector dtheta (R <- Exp(dtheta) R)
// and the position, and lift them to the 7 ambient coordinates with poseAmbientJacobian(). Their
// residuals normalise the quaternion, so the lifted Jacobian is the exact derivative in all 7
// directions (zero along the quaternion's norm) and is independent of the tangent convention.

#include <ceres/manifold.h>
#include <ceres/product_manifold.h>

#include <Eigen/Core>
#include <array>

#include "superdyna/core/geometry.h"

namespace superdyna::optim {

inline constexpr int kPoseBlockSize = 7;    ///< Ambient size of a pose block.
inline constexpr int kPoseTangentSize = 6;  ///< Tangent size: [dq, dp].

using PoseBlock = std::array<double, kPoseBlockSize>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

/// The pose block manifold, shared by every factor on poses.
using SE3Manifold =
    ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>>;

/// A pose block of which only roll and pitch may change: the tangent is [dq_x, dq_y], the rotation
/// updated as SE3Manifold's with dq = (dq_x, dq_y, 0) (left, world frame) and the position held.
/// In a gravity-aligned visual-inertial problem yaw and position are unobservable (the 4-DoF
/// gauge) while roll and pitch are observable through gravity: this fixes the gauge on one pose
/// without freezing what the IMU measures.
class RollPitchPoseManifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return kPoseBlockSize; }
  int TangentSize() const override { return 2; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;
};

/// T_w_b as a pose block (the quaternion normalised).
PoseBlock toPoseBlock(const SE3d& T_w_b);
/// The pose stored in a pose block (the quaternion normalised).
SE3d fromPoseBlock(const double* block);

/// The manifold's Plus on an SE3d: (Exp(2 delta.head(3)) R, p + delta.tail(3)).
SE3d plusPose(const SE3d& T_w_b, const Vector6d& delta);

/// d(dtheta) / d(qx, qy, qz, qw) at the quaternion stored in `q_xyzw` (any non-zero norm): the
/// rotation vector of a residual that normalises the quaternion, for the left update
/// q <- Exp(dtheta) q. Has the quaternion itself in its null space;
/// rotationTangentFromQuaternion(q) * EigenQuaternionManifold::PlusJacobian(q) = 2 I.
Eigen::Matrix<double, 3, 4> rotationTangentFromQuaternion(const double* q_xyzw);

/// Lifts a residual's tangent Jacobians at pose block `block` to the 7 ambient coordinates:
/// J_rotation = d(residual) / d(dtheta) for the left (world-frame) rotation update, J_position =
/// d(residual) / d(p_w). The result J satisfies J * PlusJacobian = [2 J_rotation, J_position].
template <int Rows>
Eigen::Matrix<double, Rows, kPoseBlockSize> poseAmbientJacobian(
    const double* block, const Eigen::Matrix<double, Rows, 3>& J_rotation,
    const Eigen::Matrix<double, Rows, 3>& J_position) {
  Eigen::Matrix<double, Rows, kPoseBlockSize> J;
  J.template leftCols<4>() = J_rotation * rotationTangentFromQuaternion(block);
  J.template rightCols<3>() = J_position;
  return J;
}

/// Ceres' PlusJacobian of SE3Manifold at a block (7 x 6), for tests and diagnostics.
Eigen::Matrix<double, kPoseBlockSize, kPoseTangentSize> posePlusJacobian(const double* block);

}  // namespace superdyna::optim

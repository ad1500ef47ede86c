#pragma once
// Rigid and similarity transforms on Eigen. Names carry frames: `T_a_b` maps points from frame b to
// frame a (p_a = T_a_b * p_b); W world, B body/IMU, C camera.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace superdyna {

/// Skew-symmetric matrix: hat(a) * b == a.cross(b).
Eigen::Matrix3d hat(const Eigen::Vector3d& v);

/// SO(3) exponential map (Rodrigues), accurate near zero.
Eigen::Matrix3d expSO3(const Eigen::Vector3d& omega);

/// SO(3) logarithm: the rotation vector of R, accurate near 0 and near pi.
Eigen::Vector3d logSO3(const Eigen::Matrix3d& R);

/// Right Jacobian of SO(3): expSO3(phi + d) ~= expSO3(phi) * expSO3(rightJacobianSO3(phi) * d) for
/// a small d [rad]. Jr(phi) = I - (1 - cos t) / t^2 hat(phi) + (t - sin t) / t^3 hat(phi)^2,
/// t = |phi|; a Taylor series is used near zero.
Eigen::Matrix3d rightJacobianSO3(const Eigen::Vector3d& phi);

/// Inverse of the right Jacobian: logSO3(expSO3(phi) * expSO3(d)) ~= phi +
/// rightJacobianInverseSO3(phi) * d. Defined for |phi| < 2 pi; accurate near zero.
Eigen::Matrix3d rightJacobianInverseSO3(const Eigen::Vector3d& phi);

/// Rotation angle of R in radians, in [0, pi]; numerically stable for small angles.
double rotationAngle(const Eigen::Matrix3d& R);

/// Projects a nearly orthonormal matrix onto SO(3) (closest rotation in Frobenius norm).
Eigen::Matrix3d nearestRotation(const Eigen::Matrix3d& M);

/// A rigid-body transform, rotation stored as a unit quaternion.
struct SE3d {
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();

  SE3d() = default;
  SE3d(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation);
  SE3d(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation);

  /// From a 4x4 or 3x4 homogeneous matrix; the rotation block is re-orthonormalised.
  static SE3d fromMatrix(const Eigen::Matrix<double, 3, 4>& M);
  static SE3d fromMatrix(const Eigen::Matrix4d& M);

  Eigen::Matrix3d rotation() const { return q.toRotationMatrix(); }
  Eigen::Matrix4d matrix() const;
  Eigen::Matrix<double, 3, 4> matrix3x4() const;

  SE3d inverse() const;
  SE3d operator*(const SE3d& other) const;
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return q * p + t; }
};

/// A similarity transform p -> s * R * p + t.
struct Sim3d {
  double s = 1.0;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();

  Sim3d() = default;
  Sim3d(double scale, const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation)
      : s(scale), R(rotation), t(translation) {}
  /// The rigid transform T as a similarity of the given scale: p -> scale * R_T * p + t_T.
  static Sim3d fromSE3(const SE3d& T, double scale = 1.0) {
    return Sim3d(scale, T.rotation(), T.t);
  }

  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return s * (R * p) + t; }
  /// Applies the similarity to a pose: rotation R * R_p, position s * R * t_p + t.
  SE3d operator*(const SE3d& pose) const;
  Sim3d inverse() const;
};

}  // namespace superdyna

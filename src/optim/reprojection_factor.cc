#include "superdyna/optim/reprojection_factor.h"

#include <cmath>
#include <string>

#include "superdyna/core/error.h"
#include "superdyna/optim/se3_manifold.h"

namespace superdyna::optim {

namespace {

template <int Rows>
using RowVector = Eigen::Matrix<double, Rows, 1>;

/// Writes a matrix into Ceres' row-major Jacobian storage.
template <int Rows, int Cols>
void storeJacobian(const Eigen::Matrix<double, Rows, Cols>& J, double* out) {
  Eigen::Map<Eigen::Matrix<double, Rows, Cols, Eigen::RowMajor>> J_out(out);
  J_out = J;
}

/// A world point in the camera frame, with what its derivatives need.
struct CameraPoint {
  CameraPoint(const SE3d& T_w_b, const SE3d& T_b_c, const Eigen::Vector3d& point_w)
      : R_c_w(T_b_c.rotation().transpose() * T_w_b.rotation().transpose()),
        p_w_rel(point_w - T_w_b.t),
        p_c(R_c_w * p_w_rel - T_b_c.rotation().transpose() * T_b_c.t) {}

  /// d(p_c) / d(dtheta) for the left update R_w_b <- Exp(dtheta) R_w_b:
  /// p_c = R_c_b R_w_b^T Exp(-dtheta) (p_w - t_w_b) + t_c_b.
  Eigen::Matrix3d jacobianRotation() const { return R_c_w * hat(p_w_rel); }

  Eigen::Matrix3d R_c_w;
  Eigen::Vector3d p_w_rel;  ///< p_w - t_w_b [m].
  Eigen::Vector3d p_c;
};

/// Normalised projection (X/Z, Y/Z) and, with 3 rows, the rectified right camera's (X - b)/Z.
template <int Rows>
RowVector<Rows> projectNormalized(const Eigen::Vector3d& p_c, double baseline_m) {
  RowVector<Rows> projection;
  projection(0) = p_c.x() / p_c.z();
  projection(1) = p_c.y() / p_c.z();
  if constexpr (Rows == 3) projection(2) = (p_c.x() - baseline_m) / p_c.z();
  return projection;
}

/// d(projectNormalized) / d(p_c).
template <int Rows>
Eigen::Matrix<double, Rows, 3> projectNormalizedJacobian(const Eigen::Vector3d& p_c,
                                                         double baseline_m) {
  const double inv_z = 1.0 / p_c.z();
  const double inv_z2 = inv_z * inv_z;
  Eigen::Matrix<double, Rows, 3> J;
  J.row(0) << inv_z, 0.0, -p_c.x() * inv_z2;
  J.row(1) << 0.0, inv_z, -p_c.y() * inv_z2;
  if constexpr (Rows == 3) J.row(2) << inv_z, 0.0, -(p_c.x() - baseline_m) * inv_z2;
  return J;
}

/// Per-row scale to whitened pixels: (fx, fy[, fx]) / sigma.
template <int Rows>
RowVector<Rows> rowWeights(const ReprojectionCamera& camera, double weight) {
  RowVector<Rows> weights;
  weights(0) = camera.fx * weight;
  weights(1) = camera.fy * weight;
  if constexpr (Rows == 3) weights(2) = camera.fx * weight;
  return weights;
}

template <int Rows>
std::optional<RowVector<Rows>> whitenedResidual(const RowVector<Rows>& observed,
                                                const ReprojectionCamera& camera, double weight,
                                                const SE3d& T_w_b, const Eigen::Vector3d& p_w) {
  const CameraPoint point(T_w_b, camera.T_b_c, p_w);
  if (point.p_c.z() < kMinProjectionDepthM) return std::nullopt;
  const RowVector<Rows> error = observed - projectNormalized<Rows>(point.p_c, camera.baseline_m);
  return RowVector<Rows>(rowWeights<Rows>(camera, weight).cwiseProduct(error));
}

/// The body of both factors' Evaluate().
template <int Rows>
bool evaluateReprojection(const RowVector<Rows>& observed, const ReprojectionCamera& camera,
                          double weight, double const* const* parameters, double* residuals,
                          double** jacobians) {
  const SE3d T_w_b = fromPoseBlock(parameters[0]);
  const Eigen::Map<const Eigen::Vector3d> p_w(parameters[1]);
  const CameraPoint point(T_w_b, camera.T_b_c, p_w);
  if (point.p_c.z() < kMinProjectionDepthM) return false;

  const RowVector<Rows> weights = rowWeights<Rows>(camera, weight);
  Eigen::Map<RowVector<Rows>> r(residuals);
  r = weights.cwiseProduct(observed - projectNormalized<Rows>(point.p_c, camera.baseline_m));
  if (jacobians == nullptr) return true;

  const Eigen::Matrix<double, Rows, 3> J_r_pc =
      -(weights.asDiagonal() * projectNormalizedJacobian<Rows>(point.p_c, camera.baseline_m));
  if (jacobians[0] != nullptr) {
    const Eigen::Matrix<double, Rows, 3> J_r_rotation = J_r_pc * point.jacobianRotation();
    const Eigen::Matrix<double, Rows, 3> J_r_position = -J_r_pc * point.R_c_w;
    storeJacobian(poseAmbientJacobian<Rows>(parameters[0], J_r_rotation, J_r_position),
                  jacobians[0]);
  }
  if (jacobians[1] != nullptr) {
    storeJacobian(Eigen::Matrix<double, Rows, 3>(J_r_pc * point.R_c_w), jacobians[1]);
  }
  return true;
}

double weightFromSigma(double sigma_px) {
  if (!(sigma_px > 0.0) || !std::isfinite(sigma_px)) {
    throw OptionError("sigma_px",
                      "must be a positive finite number, got " + std::to_string(sigma_px));
  }
  return 1.0 / sigma_px;
}

}  // namespace

double octaveSigmaPx(int octave, double sigma0_px, double scale_factor) {
  return sigma0_px * std::pow(scale_factor, octave);
}

ceres::LossFunction* newHuberLoss(double chi2_threshold) {
  return new ceres::HuberLoss(std::sqrt(chi2_threshold));
}

ReprojectionCamera ReprojectionCamera::from(const CameraModel& camera, const SE3d& T_b_c,
                                            double baseline_m) {
  ReprojectionCamera out{T_b_c, camera.fx(), camera.fy(), baseline_m};
  out.validate();
  return out;
}

void ReprojectionCamera::validate() const {
  if (!(fx > 0.0) || !(fy > 0.0) || !std::isfinite(fx) || !std::isfinite(fy)) {
    throw OptionError("camera.fx/fy", "focal lengths must be positive finite numbers");
  }
  if (!(baseline_m >= 0.0) || !std::isfinite(baseline_m)) {
    throw OptionError("camera.baseline_m", "must be a finite number >= 0");
  }
}

double stereoBaseline(const std::vector<ReprojectionCamera>& rig) {
  if (rig.size() < 2) return 0.0;
  return (rig[0].T_b_c.inverse() * rig[1].T_b_c).t.norm();
}

Eigen::Vector3d worldToCamera(const SE3d& T_w_b, const SE3d& T_b_c, const Eigen::Vector3d& p_w) {
  return CameraPoint(T_w_b, T_b_c, p_w).p_c;
}

ReprojectionFactor::ReprojectionFactor(const Eigen::Vector2d& observed_normalized,
                                       const ReprojectionCamera& camera, double sigma_px)
    : observed_(observed_normalized), camera_(camera), weight_(weightFromSigma(sigma_px)) {
  camera_.validate();
}

bool ReprojectionFactor::Evaluate(double const* const* parameters, double* residuals,
                                  double** jacobians) const {
  return evaluateReprojection<2>(observed_, camera_, weight_, parameters, residuals, jacobians);
}

std::optional<Eigen::Vector2d> ReprojectionFactor::residual(const SE3d& T_w_b,
                                                            const Eigen::Vector3d& p_w) const {
  return whitenedResidual<2>(observed_, camera_, weight_, T_w_b, p_w);
}

StereoReprojectionFactor::StereoReprojectionFactor(const Eigen::Vector3d& observed,
                                                   const ReprojectionCamera& camera,
                                                   double sigma_px)
    : observed_(observed), camera_(camera), weight_(weightFromSigma(sigma_px)) {
  camera_.validate();
  if (!(camera_.baseline_m > 0.0)) {
    throw OptionError("camera.baseline_m", "a stereo observation needs a positive baseline");
  }
}

bool StereoReprojectionFactor::Evaluate(double const* const* parameters, double* residuals,
                                        double** jacobians) const {
  return evaluateReprojection<3>(observed_, camera_, weight_, parameters, residuals, jacobians);
}

std::optional<Eigen::Vector3d> StereoReprojectionFactor::residual(
    const SE3d& T_w_b, const Eigen::Vector3d& p_w) const {
  return whitenedResidual<3>(observed_, camera_, weight_, T_w_b, p_w);
}

}  // namespace superdyna::optim

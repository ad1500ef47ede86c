#include "superdyna/dynamic/relative_motion.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>

namespace superdyna::dynamic {

namespace {

/// Adds one point's Huber-weighted reprojection term, with the left perturbation
/// [d_theta, d_t] of T_cur_prev (q' = exp(d_theta) q + d_t), to the normal equations.
void accumulate(const Eigen::Vector3d& q, const Eigen::Vector2d& x, double focal_px,
                double huber_px, double reject_px, Eigen::Matrix<double, 6, 6>& H,
                Eigen::Matrix<double, 6, 1>& b) {
  if (!(q.z() > 1e-6)) return;
  const double inv_z = 1.0 / q.z();
  const Eigen::Vector2d residual = focal_px * (q.head<2>() * inv_z - x);
  Eigen::Matrix<double, 2, 3> d_projection;
  d_projection << inv_z, 0.0, -q.x() * inv_z * inv_z, 0.0, inv_z, -q.y() * inv_z * inv_z;
  d_projection *= focal_px;
  Eigen::Matrix<double, 2, 6> J;
  J.leftCols<3>() = -d_projection * hat(q);
  J.rightCols<3>() = d_projection;
  const double norm = residual.norm();
  if (norm > reject_px) return;
  const double weight = norm <= huber_px ? 1.0 : huber_px / norm;
  H += weight * J.transpose() * J;
  b += weight * J.transpose() * residual;
}

}  // namespace

SE3d refineRelativePose(const std::vector<Eigen::Vector3d>& p_prev,
                        const std::vector<Eigen::Vector2d>& x_cur, const SE3d& T_cur_prev,
                        double focal_px, const MotionRefinementOptions& options) {
  if (static_cast<int>(p_prev.size()) < options.min_points || p_prev.size() != x_cur.size()) {
    return T_cur_prev;
  }
  Eigen::Matrix3d R = T_cur_prev.rotation();
  Eigen::Vector3d t = T_cur_prev.t;
  for (int iteration = 0; iteration < options.iterations; ++iteration) {
    // The first steps only down-weight large errors (the prediction may be far off); the later
    // ones leave out the points the pose no longer explains at all (mismatches, movers).
    const double reject_px = iteration < 2 ? std::numeric_limits<double>::infinity()
                                           : options.reject_factor * options.huber_px;
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    for (std::size_t i = 0; i < p_prev.size(); ++i) {
      accumulate(R * p_prev[i] + t, x_cur[i], focal_px, options.huber_px, reject_px, H, b);
    }
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> solver(H);
    if (solver.info() != Eigen::Success) return T_cur_prev;
    const Eigen::Matrix<double, 6, 1> step = -solver.solve(b);
    if (!step.allFinite()) return T_cur_prev;
    const Eigen::Matrix3d dR = expSO3(step.head<3>());
    R = dR * R;
    t = dR * t + step.tail<3>();
    if (step.norm() < 1e-9) break;
  }
  return SE3d(nearestRotation(R), t);
}

}  // namespace superdyna::dynamic

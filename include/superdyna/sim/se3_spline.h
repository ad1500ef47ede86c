#pragma once
// A smooth, twice-differentiable body motion for simulation: a uniform cubic B-spline on SE(3) in
// the "split" representation, position as an R^3 B-spline and rotation as a cumulative B-spline on
// SO(3) (Kim, Kim & Shin 1995; Sommer et al., "Efficient derivative computation for cumulative
// B-splines on Lie groups", CVPR 2020). Pose, velocity, acceleration, angular velocity and angular
// acceleration are evaluated in closed form, never by finite differences.
//
// In a simulated sequence the spline IS the ground truth: images and IMU samples are rendered from
// it, so it needn't reproduce the trajectory it was fitted to better than a few centimetres.

#include <functional>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"
#include "superdyna/core/trajectory.h"

namespace superdyna::sim {

/// Everything the spline gives at one time, with frames in the names (w world, b body/IMU).
struct Se3SplineState {
  TimeNs t_ns = 0;
  SE3d T_w_b;                                         ///< Pose of the body in the world.
  Eigen::Vector3d v_w = Eigen::Vector3d::Zero();      ///< Velocity in the world frame [m/s].
  Eigen::Vector3d a_w = Eigen::Vector3d::Zero();      ///< Acceleration, world frame [m/s^2].
  Eigen::Vector3d omega_b = Eigen::Vector3d::Zero();  ///< Angular velocity, body frame [rad/s].
  Eigen::Vector3d alpha_b = Eigen::Vector3d::Zero();  ///< Angular acceleration, body [rad/s^2].
};

/// Uniform cubic B-spline on SE(3), split representation.
///
/// Control point k = (R_w_k, p_w_k), k = 0..N-1, belongs to the time t0 + k * dt. The segment
/// [t0 + i dt, t0 + (i+1) dt] blends control points i-1..i+2, so the spline is defined on
///   validRange() = [t0 + dt, t0 + (N - 2) dt]   (both ends inclusive, N >= 4),
/// and every evaluation outside it throws OptionError. With u in [0, 1] the position is
///   p(u) = sum_j B_j(u) p_{i-1+j}
/// and the rotation is the cumulative form
///   R(u) = R_{i-1} prod_{j=1..3} exp(lambda_j(u) d_j),  d_j = log(R_{i-2+j}^T R_{i-1+j}),
/// with the cumulative basis lambda_j(u) = sum_{l>=j} B_l(u). The spline approximates its control
/// points (a B-spline does not pass through them); it is C2 in position and rotation.
class Se3Spline {
 public:
  /// A spline from control poses T_w_k at times t0_ns + k * knot_spacing_ns.
  /// Throws OptionError when knot_spacing_ns <= 0, there are fewer than 4 control points, or two
  /// consecutive control rotations differ by pi or more (their relative rotation is ambiguous).
  Se3Spline(TimeNs t0_ns, TimeNs knot_spacing_ns, const std::vector<SE3d>& control_poses);

  /// Fits a spline to time-stamped body poses (strictly increasing times) with knots every
  /// knot_spacing_ns. The control times are chosen so that the valid range starts at the first
  /// sample and ends at the last knot not after the last sample:
  ///   validRange() = [t_first, t_first + floor((t_last - t_first) / dt) * dt].
  /// Control points are first the samples interpolated at the knot times (linear position, slerp
  /// rotation; constant-velocity extrapolation for the two control points outside the data).
  /// Positions are then replaced by the linear least-squares fit to all samples inside the valid
  /// range (banded normal equations, with a weak pull to the interpolated values so that knots
  /// without data stay defined). Rotations, which the cumulative spline would otherwise smooth by
  /// about dt^2 / 6 times the angular acceleration, get a few approximate Gauss-Newton steps: the
  /// world-frame rotation errors at the samples are fitted by the same least squares and applied
  /// as left corrections R_k <- exp(delta_k) R_k (a first-order model, so the result is close to,
  /// not exactly at, the rotation least-squares optimum).
  /// A knot spacing of 0.1 s smooths the jitter of motion-capture ground truth and stays within
  /// millimetres (EuRoC, 200 Hz) to centimetres (OpenLORIS, 30 Hz) of it; the spline, not the
  /// samples, is then the ground truth of the simulated sequence.
  /// Gaps of up to max(1 s, 10 knot spacings) between samples are bridged by the interpolation;
  /// longer gaps (separate recordings, as in OpenLORIS files) throw InputError: fit each part on
  /// its own (see splitAtGaps).
  /// Throws OptionError when knot_spacing_ns <= 0 or the samples span less than one knot spacing,
  /// InputError when there are fewer than 2 samples or their times are not strictly increasing.
  static Se3Spline fit(const Trajectory& samples, TimeNs knot_spacing_ns);

  /// A spline for procedural motion: control poses are `pose_at(t)` (T_w_b at t [ns]) at the
  /// knot times, placed so that the valid range covers `range` (it starts at range.begin and ends
  /// at the first knot at or after range.end). `pose_at` is called from range.begin - dt to
  /// range.end + 2 dt. The spline approximates the function (error about dt^2 / 6 times its second
  /// derivative) and is from then on the ground truth.
  static Se3Spline fromFunction(const std::function<SE3d(TimeNs)>& pose_at, TimeRange range,
                                TimeNs knot_spacing_ns);

  /// Times where the spline can be evaluated: [t0 + dt, t0 + (N - 2) dt], both inclusive.
  TimeRange validRange() const;
  TimeNs knotSpacingNs() const { return dt_ns_; }
  TimeNs startTimeNs() const { return t0_ns_; }  ///< Time t0 of control point 0 [ns].
  const std::vector<SE3d>& controlPoses() const { return control_poses_; }

  /// Pose T_w_b(t) of the body in the world.
  SE3d pose(TimeNs t_ns) const;
  /// Position p_w(t) of the body origin in the world [m].
  Eigen::Vector3d position(TimeNs t_ns) const;
  /// Rotation R_w_b(t).
  Eigen::Matrix3d rotation(TimeNs t_ns) const;
  /// Velocity v_w(t) = dp_w/dt in the world frame [m/s].
  Eigen::Vector3d velocity(TimeNs t_ns) const;
  /// Acceleration a_w(t) = d^2p_w/dt^2 in the world frame [m/s^2] (gravity not included).
  Eigen::Vector3d acceleration(TimeNs t_ns) const;
  /// Angular velocity omega_b(t) in the body frame: R^T dR/dt = hat(omega_b) [rad/s].
  Eigen::Vector3d angularVelocity(TimeNs t_ns) const;
  /// Angular acceleration d(omega_b)/dt in the body frame [rad/s^2].
  Eigen::Vector3d angularAcceleration(TimeNs t_ns) const;
  /// Pose and all derivatives at once (cheaper than the separate calls).
  Se3SplineState state(TimeNs t_ns) const;

 private:
  /// Where t falls: segment i (blends control points i-1..i+2) and u in [0, 1].
  struct Segment {
    std::size_t i = 0;
    double u = 0.0;
  };
  struct RotationResult {
    Eigen::Matrix3d R_w_b;
    Eigen::Vector3d omega_b;
    Eigen::Vector3d alpha_b;
  };

  Segment locate(TimeNs t_ns) const;
  Eigen::Vector3d positionDerivative(const Segment& s, int order) const;
  RotationResult evaluateRotation(const Segment& s) const;

  TimeNs t0_ns_ = 0;
  TimeNs dt_ns_ = 0;
  std::vector<SE3d> control_poses_;
  std::vector<Eigen::Matrix3d> R_w_k_;  ///< Control rotations as matrices.
  std::vector<Eigen::Vector3d> p_w_k_;  ///< Control positions [m].
  std::vector<Eigen::Vector3d> d_k_;    ///< d_k = log(R_{k-1}^T R_k) for k >= 1; d_0 unused.
};

/// Splits a trajectory wherever two consecutive samples are more than max_gap_ns apart
/// (e.g. the separate recordings of an OpenLORIS ground-truth file). Keeps the order.
std::vector<Trajectory> splitAtGaps(const Trajectory& trajectory, TimeNs max_gap_ns);

}  // namespace superdyna::sim

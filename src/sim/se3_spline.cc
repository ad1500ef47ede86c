#include "superdyna/sim/se3_spline.h"

#include <fmt/format.h>

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <functional>

#include "superdyna/core/error.h"

namespace superdyna::sim {

namespace {

/// Relative rotations at least this close to pi are rejected (their axis is ambiguous).
constexpr double kMaxRelativeAngleRad = M_PI - 1e-6;
/// Weight of the pull of each control value to its prior (the interpolated position, a zero
/// rotation correction) in the least-squares fits, relative to a sample's weight of 1: keeps
/// knots without data defined while biasing knots with data by a negligible amount.
constexpr double kPriorWeight = 1e-3;
/// fit() bridges gaps between samples up to max(this, kMaxGapKnots knot spacings).
constexpr TimeNs kMaxBridgedGapNs = kNsPerSecond;
constexpr TimeNs kMaxGapKnots = 10;
/// Approximate Gauss-Newton steps on the control rotations in fit().
constexpr int kRotationIterations = 3;

/// d^order/du^order of the uniform cubic B-spline basis B_0..B_3 at u in [0, 1].
Eigen::Vector4d basis(double u, int order) {
  const double v = 1.0 - u;
  switch (order) {
    case 0:
      return Eigen::Vector4d(v * v * v, 3.0 * u * u * u - 6.0 * u * u + 4.0,
                             -3.0 * u * u * u + 3.0 * u * u + 3.0 * u + 1.0, u * u * u) /
             6.0;
    case 1:
      return Eigen::Vector4d(-v * v, 3.0 * u * u - 4.0 * u, -3.0 * u * u + 2.0 * u + 1.0, u * u) /
             2.0;
    default:
      return Eigen::Vector4d(v, 3.0 * u - 2.0, 1.0 - 3.0 * u, u);
  }
}

/// d^order/du^order of the cumulative basis lambda_j = sum_{l >= j} B_l, j = 1..3 (lambda_0 = 1).
Eigen::Vector3d cumulativeBasis(double u, int order) {
  const double v = 1.0 - u;
  switch (order) {
    case 0:
      return Eigen::Vector3d(5.0 + 3.0 * u - 3.0 * u * u + u * u * u,
                             1.0 + 3.0 * u + 3.0 * u * u - 2.0 * u * u * u, u * u * u) /
             6.0;
    case 1:
      return Eigen::Vector3d(v * v, 1.0 + 2.0 * u - 2.0 * u * u, u * u) / 2.0;
    default:
      return Eigen::Vector3d(-v, 1.0 - 2.0 * u, u);
  }
}

/// Rotation from R_a (s = 0) to R_b (s = 1) at constant angular velocity (shortest path).
Eigen::Matrix3d interpolateRotation(const Eigen::Matrix3d& R_a, const Eigen::Matrix3d& R_b,
                                    double s) {
  return R_a * expSO3(s * logSO3(R_a.transpose() * R_b));
}

/// Pose of the samples at t (linear position, slerp rotation); t within the samples' range.
SE3d interpolatePose(const Trajectory& samples, TimeNs t_ns) {
  const auto after = std::upper_bound(samples.begin(), samples.end(), t_ns,
                                      [](TimeNs t, const StampedPose& p) { return t < p.t_ns; });
  if (after == samples.begin()) return samples.front().T_w_x;
  if (after == samples.end()) return samples.back().T_w_x;
  const StampedPose& a = *(after - 1);
  const StampedPose& b = *after;
  const double s = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  return SE3d(interpolateRotation(a.T_w_x.rotation(), b.T_w_x.rotation(), s),
              Eigen::Vector3d((1.0 - s) * a.T_w_x.t + s * b.T_w_x.t));
}

/// The pose one knot beyond `last`, continuing the motion from `before_last` to `last`.
SE3d extrapolatePose(const SE3d& before_last, const SE3d& last) {
  const Eigen::Matrix3d R_last = last.rotation();
  return SE3d(interpolateRotation(before_last.rotation(), R_last, 2.0),
              Eigen::Vector3d(2.0 * last.t - before_last.t));
}

void checkSamples(const Trajectory& samples, TimeNs knot_spacing_ns) {
  if (knot_spacing_ns <= 0) throw OptionError("knot_spacing_ns", "must be positive");
  if (samples.size() < 2) throw InputError("spline fit: needs at least two samples");
  const TimeNs max_gap_ns = std::max(kMaxBridgedGapNs, kMaxGapKnots * knot_spacing_ns);
  for (std::size_t k = 1; k < samples.size(); ++k) {
    const TimeNs gap_ns = samples[k].t_ns - samples[k - 1].t_ns;
    if (gap_ns <= 0) {
      throw InputError(fmt::format("spline fit: sample times not strictly increasing at {} s",
                                   formatNsAsSeconds(samples[k].t_ns)));
    }
    if (gap_ns > max_gap_ns) {
      throw InputError(fmt::format(
          "spline fit: gap of {} s before {} s is longer than {} s; fit each part on its own",
          formatNsAsSeconds(gap_ns), formatNsAsSeconds(samples[k].t_ns),
          formatNsAsSeconds(max_gap_ns)));
    }
  }
  if (samples.back().t_ns - samples.front().t_ns < knot_spacing_ns) {
    throw OptionError("knot_spacing_ns", "longer than the time spanned by the samples");
  }
}

/// Control poses at t0 + k dt: interpolated samples, extrapolated at both ends.
std::vector<SE3d> interpolatedControlPoses(const Trajectory& samples, TimeNs t0_ns, TimeNs dt_ns,
                                           std::size_t count) {
  std::vector<SE3d> poses(count);
  for (std::size_t k = 1; k + 1 < count; ++k) {
    poses[k] = interpolatePose(samples, t0_ns + static_cast<TimeNs>(k) * dt_ns);
  }
  poses.front() = extrapolatePose(poses[2], poses[1]);
  poses.back() = extrapolatePose(poses[count - 3], poses[count - 2]);
  return poses;
}

/// Linear least squares for R^3 control values x_k of a uniform cubic B-spline with the knots of
/// `spline`: minimises sum_s |sum_j B_j(u_s) x_{i_s - 1 + j} - y_s|^2 + w sum_k |x_k - prior_k|^2
/// over the samples inside the valid range (w = kPriorWeight). The normal matrix is
/// banded (bandwidth 3); it is factorised once and reused for every right-hand side.
class SplineLeastSquares {
 public:
  SplineLeastSquares(const Trajectory& samples, const Se3Spline& spline)
      : count_(static_cast<Eigen::Index>(spline.controlPoses().size())) {
    const TimeRange valid = spline.validRange();
    const TimeNs t0_ns = spline.startTimeNs();
    const TimeNs dt_ns = spline.knotSpacingNs();
    for (std::size_t s = 0; s < samples.size(); ++s) {
      if (!valid.contains(samples[s].t_ns)) continue;
      const TimeNs i = std::min((samples[s].t_ns - t0_ns) / dt_ns, TimeNs{count_ - 3});
      const double u =
          static_cast<double>(samples[s].t_ns - t0_ns - i * dt_ns) / static_cast<double>(dt_ns);
      rows_.push_back({s, static_cast<Eigen::Index>(i - 1), basis(u, 0)});
    }
    factorise();
  }

  /// Control values for targets y_s = target(s) (s indexes `samples`) and the given prior.
  Eigen::MatrixX3d solve(const std::function<Eigen::Vector3d(std::size_t)>& target,
                         const Eigen::MatrixX3d& prior) const {
    Eigen::MatrixX3d rhs = kPriorWeight * prior;
    for (const Row& row : rows_) {
      const Eigen::RowVector3d y = target(row.sample).transpose();
      for (int r = 0; r < 4; ++r) {
        rhs.row(row.first + r) += row.b[r] * y;
      }
    }
    return solver_.solve(rhs);
  }

 private:
  struct Row {
    std::size_t sample;
    Eigen::Index first;  ///< Index of the first of the 4 control points the sample depends on.
    Eigen::Vector4d b;   ///< Their basis weights.
  };

  void factorise() {
    std::vector<Eigen::Triplet<double>> entries;
    entries.reserve(static_cast<std::size_t>(count_) + 16 * rows_.size());
    for (Eigen::Index k = 0; k < count_; ++k) {
      entries.emplace_back(k, k, kPriorWeight);
    }
    for (const Row& row : rows_) {
      for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 4; ++c) {
          entries.emplace_back(row.first + r, row.first + c, row.b[r] * row.b[c]);
        }
      }
    }
    Eigen::SparseMatrix<double> normal(count_, count_);
    normal.setFromTriplets(entries.begin(), entries.end());
    solver_.compute(normal);
    if (solver_.info() != Eigen::Success) {
      throw InputError("spline fit: least-squares system is singular");
    }
  }

  Eigen::Index count_;
  std::vector<Row> rows_;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver_;
};

/// Replaces the control positions by their least-squares fit to the sample positions, pulled
/// weakly to their current values.
void fitPositions(const Trajectory& samples, const SplineLeastSquares& least_squares,
                  std::vector<SE3d>& control_poses) {
  Eigen::MatrixX3d prior(static_cast<Eigen::Index>(control_poses.size()), 3);
  for (std::size_t k = 0; k < control_poses.size(); ++k) {
    prior.row(static_cast<Eigen::Index>(k)) = control_poses[k].t.transpose();
  }
  const Eigen::MatrixX3d positions =
      least_squares.solve([&](std::size_t s) { return samples[s].T_w_x.t; }, prior);
  for (std::size_t k = 0; k < control_poses.size(); ++k) {
    control_poses[k].t = positions.row(static_cast<Eigen::Index>(k)).transpose();
  }
}

/// One approximate Gauss-Newton step on the control rotations: the world-frame rotation errors
/// e_s = log(R_s R(t_s)^T) are fitted by a B-spline of corrections delta_k (the first-order
/// effect of R_k <- exp(delta_k) R_k on a cumulative spline whose consecutive control rotations
/// are close), and the corrections are applied. A correction common to all control points is
/// reproduced exactly.
void refineRotations(const Trajectory& samples, const SplineLeastSquares& least_squares,
                     const Se3Spline& current, std::vector<SE3d>& control_poses) {
  const auto errorAt = [&](std::size_t s) {
    const Eigen::Matrix3d R_spline = current.rotation(samples[s].t_ns);
    return logSO3(samples[s].T_w_x.rotation() * R_spline.transpose());
  };
  const auto count = static_cast<Eigen::Index>(control_poses.size());
  const Eigen::MatrixX3d delta = least_squares.solve(errorAt, Eigen::MatrixX3d::Zero(count, 3));
  for (std::size_t k = 0; k < control_poses.size(); ++k) {
    const Eigen::Vector3d delta_k = delta.row(static_cast<Eigen::Index>(k)).transpose();
    control_poses[k].q = Eigen::Quaterniond(expSO3(delta_k) * control_poses[k].rotation());
  }
}

}  // namespace

Se3Spline::Se3Spline(TimeNs t0_ns, TimeNs knot_spacing_ns, const std::vector<SE3d>& control_poses)
    : t0_ns_(t0_ns), dt_ns_(knot_spacing_ns), control_poses_(control_poses) {
  if (dt_ns_ <= 0) throw OptionError("knot_spacing_ns", "must be positive");
  if (control_poses_.size() < 4) {
    throw OptionError("control_poses", fmt::format("a cubic spline needs at least 4, got {}",
                                                   control_poses_.size()));
  }
  R_w_k_.reserve(control_poses_.size());
  p_w_k_.reserve(control_poses_.size());
  d_k_.assign(control_poses_.size(), Eigen::Vector3d::Zero());
  for (std::size_t k = 0; k < control_poses_.size(); ++k) {
    R_w_k_.push_back(control_poses_[k].rotation());
    p_w_k_.push_back(control_poses_[k].t);
    if (k == 0) continue;
    d_k_[k] = logSO3(R_w_k_[k - 1].transpose() * R_w_k_[k]);
    if (d_k_[k].norm() >= kMaxRelativeAngleRad) {
      throw OptionError("control_poses",
                        fmt::format("rotation between control points {} and {} is pi or more; "
                                    "use a smaller knot spacing",
                                    k - 1, k));
    }
  }
}

Se3Spline Se3Spline::fit(const Trajectory& samples, TimeNs knot_spacing_ns) {
  checkSamples(samples, knot_spacing_ns);
  const TimeNs t_first = samples.front().t_ns;
  const TimeNs segments = (samples.back().t_ns - t_first) / knot_spacing_ns;
  const auto count = static_cast<std::size_t>(segments + 3);
  const TimeNs t0_ns = t_first - knot_spacing_ns;
  std::vector<SE3d> control_poses =
      interpolatedControlPoses(samples, t0_ns, knot_spacing_ns, count);
  Se3Spline spline(t0_ns, knot_spacing_ns, control_poses);
  const SplineLeastSquares least_squares(samples, spline);
  fitPositions(samples, least_squares, control_poses);
  for (int iteration = 0; iteration < kRotationIterations; ++iteration) {
    spline = Se3Spline(t0_ns, knot_spacing_ns, control_poses);
    refineRotations(samples, least_squares, spline, control_poses);
  }
  return Se3Spline(t0_ns, knot_spacing_ns, control_poses);
}

Se3Spline Se3Spline::fromFunction(const std::function<SE3d(TimeNs)>& pose_at, TimeRange range,
                                  TimeNs knot_spacing_ns) {
  if (knot_spacing_ns <= 0) throw OptionError("knot_spacing_ns", "must be positive");
  if (range.end < range.begin) throw OptionError("range", "end is before begin");
  const TimeNs span_ns = range.end - range.begin;
  const TimeNs segments = std::max<TimeNs>(1, (span_ns + knot_spacing_ns - 1) / knot_spacing_ns);
  const TimeNs t0_ns = range.begin - knot_spacing_ns;
  std::vector<SE3d> control_poses;
  control_poses.reserve(static_cast<std::size_t>(segments + 3));
  for (TimeNs k = 0; k < segments + 3; ++k) {
    control_poses.push_back(pose_at(t0_ns + k * knot_spacing_ns));
  }
  return Se3Spline(t0_ns, knot_spacing_ns, control_poses);
}

TimeRange Se3Spline::validRange() const {
  const auto n = static_cast<TimeNs>(control_poses_.size());
  return {t0_ns_ + dt_ns_, t0_ns_ + (n - 2) * dt_ns_};
}

Se3Spline::Segment Se3Spline::locate(TimeNs t_ns) const {
  const TimeRange valid = validRange();
  if (!valid.contains(t_ns)) {
    throw OptionError("t_ns", fmt::format("{} s is outside the spline's valid range [{}, {}] s",
                                          formatNsAsSeconds(t_ns), formatNsAsSeconds(valid.begin),
                                          formatNsAsSeconds(valid.end)));
  }
  const auto last_segment = static_cast<TimeNs>(control_poses_.size()) - 3;
  const TimeNs i = std::min((t_ns - t0_ns_) / dt_ns_, last_segment);
  const double u = static_cast<double>(t_ns - t0_ns_ - i * dt_ns_) / static_cast<double>(dt_ns_);
  return {static_cast<std::size_t>(i), u};
}

Eigen::Vector3d Se3Spline::positionDerivative(const Segment& s, int order) const {
  const Eigen::Vector4d b = basis(s.u, order);
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (std::size_t j = 0; j < 4; ++j) {
    p += b[static_cast<Eigen::Index>(j)] * p_w_k_[s.i - 1 + j];
  }
  return p / std::pow(nsToSeconds(dt_ns_), order);
}

Se3Spline::RotationResult Se3Spline::evaluateRotation(const Segment& s) const {
  // R = R_{i-1} A_1 A_2 A_3 with A_j = exp(lambda_j d_j). The body rates follow the recursion of
  // Sommer et al.: omega_j = A_j^T omega_{j-1} + dlambda_j d_j and
  // alpha_j = A_j^T alpha_{j-1} + ddlambda_j d_j + omega_j x (dlambda_j d_j).
  const double dt_s = nsToSeconds(dt_ns_);
  const Eigen::Vector3d lambda = cumulativeBasis(s.u, 0);
  const Eigen::Vector3d dlambda = cumulativeBasis(s.u, 1) / dt_s;
  const Eigen::Vector3d ddlambda = cumulativeBasis(s.u, 2) / (dt_s * dt_s);
  RotationResult r{R_w_k_[s.i - 1], Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  for (std::size_t j = 0; j < 3; ++j) {
    const auto jj = static_cast<Eigen::Index>(j);
    const Eigen::Vector3d& d = d_k_[s.i + j];
    const Eigen::Matrix3d A_t = expSO3(lambda[jj] * d).transpose();
    const Eigen::Vector3d rate = dlambda[jj] * d;
    r.omega_b = A_t * r.omega_b + rate;
    r.alpha_b = A_t * r.alpha_b + ddlambda[jj] * d + r.omega_b.cross(rate);
    r.R_w_b = r.R_w_b * A_t.transpose();
  }
  return r;
}

SE3d Se3Spline::pose(TimeNs t_ns) const {
  const Segment s = locate(t_ns);
  return SE3d(evaluateRotation(s).R_w_b, positionDerivative(s, 0));
}

Eigen::Vector3d Se3Spline::position(TimeNs t_ns) const {
  return positionDerivative(locate(t_ns), 0);
}

Eigen::Matrix3d Se3Spline::rotation(TimeNs t_ns) const {
  return evaluateRotation(locate(t_ns)).R_w_b;
}

Eigen::Vector3d Se3Spline::velocity(TimeNs t_ns) const {
  return positionDerivative(locate(t_ns), 1);
}

Eigen::Vector3d Se3Spline::acceleration(TimeNs t_ns) const {
  return positionDerivative(locate(t_ns), 2);
}

Eigen::Vector3d Se3Spline::angularVelocity(TimeNs t_ns) const {
  return evaluateRotation(locate(t_ns)).omega_b;
}

Eigen::Vector3d Se3Spline::angularAcceleration(TimeNs t_ns) const {
  return evaluateRotation(locate(t_ns)).alpha_b;
}

Se3SplineState Se3Spline::state(TimeNs t_ns) const {
  const Segment s = locate(t_ns);
  const RotationResult r = evaluateRotation(s);
  Se3SplineState out;
  out.t_ns = t_ns;
  out.T_w_b = SE3d(r.R_w_b, positionDerivative(s, 0));
  out.v_w = positionDerivative(s, 1);
  out.a_w = positionDerivative(s, 2);
  out.omega_b = r.omega_b;
  out.alpha_b = r.alpha_b;
  return out;
}

std::vector<Trajectory> splitAtGaps(const Trajectory& trajectory, TimeNs max_gap_ns) {
  std::vector<Trajectory> parts;
  for (std::size_t k = 0; k < trajectory.size(); ++k) {
    if (k == 0 || trajectory[k].t_ns - trajectory[k - 1].t_ns > max_gap_ns) parts.emplace_back();
    parts.back().push_back(trajectory[k]);
  }
  return parts;
}

}  // namespace superdyna::sim

#include "superdyna/core/camera_model.h"

#include <fmt/format.h>

#include <Eigen/LU>
#include <cmath>
#include <utility>

#include "superdyna/core/error.h"

namespace superdyna {

namespace {

std::size_t expectedCoefficientCount(DistortionModel model, std::size_t given) {
  switch (model) {
    case DistortionModel::kNone:
      return 0;
    case DistortionModel::kRadialTangential:
      return given == 5 ? 5 : 4;
    case DistortionModel::kEquidistant:
      return 4;
  }
  return 0;
}

Eigen::Vector2d distortRadTan(const std::vector<double>& k, const Eigen::Vector2d& n) {
  const double x = n.x(), y = n.y();
  const double r2 = x * x + y * y;
  const double k3 = k.size() > 4 ? k[4] : 0.0;
  const double radial = 1.0 + r2 * (k[0] + r2 * (k[1] + r2 * k3));
  return {x * radial + 2.0 * k[2] * x * y + k[3] * (r2 + 2.0 * x * x),
          y * radial + k[2] * (r2 + 2.0 * y * y) + 2.0 * k[3] * x * y};
}

Eigen::Vector2d distortEquidistant(const std::vector<double>& k, const Eigen::Vector2d& n) {
  const double r = n.norm();
  if (r < 1e-12) return n;
  const double theta = std::atan(r);
  const double t2 = theta * theta;
  const double theta_d = theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
  return n * (theta_d / r);
}

/// theta_d(theta) of the equidistant model and its derivative.
std::pair<double, double> equidistantAngle(const std::vector<double>& k, double theta) {
  const double t2 = theta * theta;
  const double value = theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
  const double slope =
      1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + 9.0 * t2 * k[3])));
  return {value, slope};
}

/// Bearing of a distorted normalised point under the equidistant model, solving theta_d(theta) =
/// r_d by Newton's method on the angle, so that fields of view beyond 180 degrees work.
std::optional<Eigen::Vector3d> unprojectEquidistant(const std::vector<double>& k,
                                                    const Eigen::Vector2d& distorted) {
  const double r_d = distorted.norm();
  if (r_d < 1e-12) return Eigen::Vector3d::UnitZ();
  double theta = r_d;
  for (int i = 0; i < 30; ++i) {
    const auto [value, slope] = equidistantAngle(k, theta);
    if (std::abs(value - r_d) < 1e-14) break;
    if (slope <= 1e-9) return std::nullopt;
    theta -= (value - r_d) / slope;
  }
  if (!std::isfinite(theta) || std::abs(equidistantAngle(k, theta).first - r_d) > 1e-9 ||
      theta < 0.0 || theta > M_PI) {
    return std::nullopt;
  }
  const Eigen::Vector2d direction = distorted / r_d;
  return Eigen::Vector3d(std::sin(theta) * direction.x(), std::sin(theta) * direction.y(),
                         std::cos(theta));
}

}  // namespace

std::optional<DistortionModel> parseDistortionModel(const std::string& name) {
  if (name == "none") return DistortionModel::kNone;
  if (name == "radial-tangential" || name == "radtan" || name == "plumb_bob") {
    return DistortionModel::kRadialTangential;
  }
  if (name == "equidistant" || name == "fisheye") return DistortionModel::kEquidistant;
  return std::nullopt;
}

std::string toString(DistortionModel model) {
  switch (model) {
    case DistortionModel::kNone:
      return "none";
    case DistortionModel::kRadialTangential:
      return "radial-tangential";
    case DistortionModel::kEquidistant:
      return "equidistant";
  }
  return "unknown";
}

CameraModel::CameraModel(int width, int height, double fx, double fy, double cx, double cy,
                         DistortionModel model, std::vector<double> coefficients)
    : width_(width),
      height_(height),
      fx_(fx),
      fy_(fy),
      cx_(cx),
      cy_(cy),
      model_(model),
      coefficients_(std::move(coefficients)) {
  if (width <= 0 || height <= 0) throw OptionError("resolution", "must be positive");
  if (!(fx > 0.0) || !(fy > 0.0)) throw OptionError("intrinsics", "focal lengths must be > 0");
  if (!std::isfinite(cx) || !std::isfinite(cy)) {
    throw OptionError("intrinsics", "principal point must be finite");
  }
  const std::size_t expected = expectedCoefficientCount(model, coefficients_.size());
  if (coefficients_.size() != expected) {
    throw OptionError("distortion_coefficients",
                      fmt::format("{} needs {} coefficients, got {}", toString(model), expected,
                                  coefficients_.size()));
  }
}

Eigen::Vector2d CameraModel::distort(const Eigen::Vector2d& normalized) const {
  switch (model_) {
    case DistortionModel::kNone:
      return normalized;
    case DistortionModel::kRadialTangential:
      return distortRadTan(coefficients_, normalized);
    case DistortionModel::kEquidistant:
      return distortEquidistant(coefficients_, normalized);
  }
  return normalized;
}

Eigen::Matrix2d CameraModel::distortJacobian(const Eigen::Vector2d& normalized) const {
  // Central differences: used only inside the iterative undistortion, where the exact Jacobian
  // affects the convergence speed, not the converged answer.
  constexpr double kStep = 1e-7;
  Eigen::Matrix2d J;
  for (int i = 0; i < 2; ++i) {
    Eigen::Vector2d delta = Eigen::Vector2d::Zero();
    delta[i] = kStep;
    J.col(i) = (distort(normalized + delta) - distort(normalized - delta)) / (2.0 * kStep);
  }
  return J;
}

std::optional<Eigen::Vector2d> CameraModel::undistort(const Eigen::Vector2d& distorted) const {
  if (model_ == DistortionModel::kNone) return distorted;
  constexpr int kMaxIterations = 30;
  constexpr double kTolerance = 1e-13;
  Eigen::Vector2d x = distorted;
  for (int i = 0; i < kMaxIterations; ++i) {
    const Eigen::Vector2d residual = distort(x) - distorted;
    if (residual.squaredNorm() < kTolerance * kTolerance) return x;
    const Eigen::Matrix2d J = distortJacobian(x);
    if (std::abs(J.determinant()) < 1e-12) return std::nullopt;
    x -= J.inverse() * residual;
    if (!x.allFinite()) return std::nullopt;
  }
  if ((distort(x) - distorted).norm() < 1e-9) return x;
  return std::nullopt;
}

std::optional<Eigen::Vector2d> CameraModel::project(const Eigen::Vector3d& p_c) const {
  if (p_c.z() <= 1e-9) return std::nullopt;
  const Eigen::Vector2d d = distort(p_c.head<2>() / p_c.z());
  return Eigen::Vector2d(fx_ * d.x() + cx_, fy_ * d.y() + cy_);
}

std::optional<Eigen::Vector3d> CameraModel::unproject(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d distorted((pixel.x() - cx_) / fx_, (pixel.y() - cy_) / fy_);
  if (model_ == DistortionModel::kEquidistant)
    return unprojectEquidistant(coefficients_, distorted);
  const auto normalized = undistort(distorted);
  if (!normalized) return std::nullopt;
  return Eigen::Vector3d(normalized->x(), normalized->y(), 1.0).normalized();
}

bool CameraModel::isInImage(const Eigen::Vector2d& pixel, double border) const {
  return pixel.x() >= border && pixel.y() >= border && pixel.x() <= width_ - 1 - border &&
         pixel.y() <= height_ - 1 - border;
}

}  // namespace superdyna

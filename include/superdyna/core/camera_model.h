#pragma once
// Pinhole camera with optional lens distortion, as calibrated for EuRoC / Kalibr:
//  - radial-tangential (OpenCV "plumb bob"): k1, k2, p1, p2[, k3];
//  - equidistant (Kannala-Brandt, OpenCV fisheye): k1, k2, k3, k4.
// Coordinates: a point X_c in the camera frame (z forward, x right, y down) projects to the
// pixel u = fx * x_d + cx, v = fy * y_d + cy, with (x_d, y_d) the distorted normalised point.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

namespace superdyna {

enum class DistortionModel { kNone, kRadialTangential, kEquidistant };

/// "none", "radial-tangential" (also "radtan", "plumb_bob"), "equidistant" (also "fisheye").
/// Returns nullopt for other names.
std::optional<DistortionModel> parseDistortionModel(const std::string& name);
std::string toString(DistortionModel model);

class CameraModel {
 public:
  CameraModel() = default;
  /// Throws OptionError when a focal length or the size is not positive, or the number of
  /// coefficients does not fit the model (radtan 4 or 5, equidistant 4, none 0).
  CameraModel(int width, int height, double fx, double fy, double cx, double cy,
              DistortionModel model = DistortionModel::kNone,
              std::vector<double> coefficients = {});

  int width() const { return width_; }
  int height() const { return height_; }
  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  DistortionModel distortionModel() const { return model_; }
  const std::vector<double>& coefficients() const { return coefficients_; }

  /// Pixel of a camera-frame point; nullopt when the point is not in front of the camera.
  std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& p_c) const;

  /// Unit-norm bearing (camera frame) of a pixel, undoing the distortion by Newton's method;
  /// nullopt when that does not converge (far outside the calibrated field). Equidistant
  /// cameras can return bearings beyond 90 degrees off the axis (z <= 0).
  std::optional<Eigen::Vector3d> unproject(const Eigen::Vector2d& pixel) const;

  /// Distortion of a normalised image point (x/z, y/z).
  Eigen::Vector2d distort(const Eigen::Vector2d& normalized) const;
  /// Inverse of distort(); nullopt when it does not converge.
  std::optional<Eigen::Vector2d> undistort(const Eigen::Vector2d& distorted) const;

  bool isInImage(const Eigen::Vector2d& pixel, double border = 0.0) const;

 private:
  Eigen::Matrix2d distortJacobian(const Eigen::Vector2d& normalized) const;

  int width_ = 0;
  int height_ = 0;
  double fx_ = 1.0, fy_ = 1.0, cx_ = 0.0, cy_ = 0.0;
  DistortionModel model_ = DistortionModel::kNone;
  std::vector<double> coefficients_;
};

}  // namespace superdyna

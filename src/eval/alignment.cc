#include "superdyna/eval/alignment.h"

#include <fmt/format.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <numbers>

#include "superdyna/core/error.h"

namespace superdyna::eval {
namespace {

// Degeneracy thresholds. Positions are in metres; a spread below a nanometre (relative to the
// coordinate magnitude, so that UTM-sized coordinates are not penalised by rounding) is no spread,
// and a point set whose second principal extent is a millionth of its first is a line: the
// rotation about that line is then decided by rounding noise, not by the data.
constexpr double kCoincidentRelative = 1e-9;
constexpr double kCollinearRatio = 1e-6;

constexpr int kMinPoints = 3;

/// Standard deviations of the centred points along their principal axes, largest first.
Eigen::Vector3d principalExtents(const Eigen::Matrix3Xd& centred) {
  const Eigen::Matrix3d scatter =
      centred * centred.transpose() / static_cast<double>(centred.cols());
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(scatter);
  return svd.singularValues().cwiseSqrt();
}

/// Throws InputError when the points coincide or lie on one line.
void requireSpreadInTwoDirections(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& centred,
                                  const char* which) {
  const Eigen::Vector3d extent = principalExtents(centred);
  const double magnitude = std::max(1.0, points.cwiseAbs().maxCoeff());
  if (extent(0) <= kCoincidentRelative * magnitude) {
    throw InputError(fmt::format(
        "cannot align: all {} {} positions coincide (spread {:.3g} m); a rotation needs poses "
        "spread in at least two directions",
        points.cols(), which, extent(0)));
  }
  if (extent(1) <= kCollinearRatio * extent(0)) {
    throw InputError(fmt::format(
        "cannot align: the {} {} positions lie on one line (principal extents {:.3g} m and {:.3g} "
        "m), so the rotation about that line is undetermined; use more poses or --align none",
        points.cols(), which, extent(0), extent(1)));
  }
}

std::string lowercase(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

}  // namespace

AlignmentMode parseAlignmentMode(const std::string& name) {
  const std::string lower = lowercase(name);
  if (lower == "none") return AlignmentMode::kNone;
  if (lower == "se3") return AlignmentMode::kSE3;
  if (lower == "sim3") return AlignmentMode::kSim3;
  throw OptionError("align",
                    fmt::format("unknown alignment '{}' (expected none, se3 or sim3)", name));
}

std::string toString(AlignmentMode mode) {
  switch (mode) {
    case AlignmentMode::kNone:
      return "none";
    case AlignmentMode::kSE3:
      return "se3";
    case AlignmentMode::kSim3:
      return "sim3";
  }
  return "unknown";
}

Sim3d umeyamaAlignment(const Eigen::Matrix3Xd& src, const Eigen::Matrix3Xd& dst, bool with_scale) {
  if (src.cols() != dst.cols()) {
    throw InputError(fmt::format("cannot align {} positions to {} positions: counts differ",
                                 src.cols(), dst.cols()));
  }
  const Eigen::Index n = src.cols();
  if (n < kMinPoints) {
    throw InputError(fmt::format("cannot align: needs at least {} poses, got {}", kMinPoints, n));
  }
  const Eigen::Vector3d mean_src = src.rowwise().mean();
  const Eigen::Vector3d mean_dst = dst.rowwise().mean();
  const Eigen::Matrix3Xd centred_src = src.colwise() - mean_src;
  const Eigen::Matrix3Xd centred_dst = dst.colwise() - mean_dst;
  requireSpreadInTwoDirections(src, centred_src, "estimate");
  requireSpreadInTwoDirections(dst, centred_dst, "ground-truth");

  // Umeyama eq. (38)-(42): cross-covariance Sigma = U D V^T; S flips the last axis when U V^T
  // would be a reflection, so that R is a proper rotation.
  const double inv_n = 1.0 / static_cast<double>(n);
  const Eigen::Matrix3d covariance = centred_dst * centred_src.transpose() * inv_n;
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(covariance,
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d d = svd.singularValues();
  if (d(1) <= kCollinearRatio * kCollinearRatio * d(0)) {
    throw InputError(
        "cannot align: the estimate and ground-truth positions are not correlated in two "
        "directions, so no rotation fits them");
  }
  Eigen::Vector3d reflection_fix = Eigen::Vector3d::Ones();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) reflection_fix(2) = -1.0;

  Sim3d result;
  result.R = svd.matrixU() * reflection_fix.asDiagonal() * svd.matrixV().transpose();
  if (with_scale) {
    const double variance_src = centred_src.squaredNorm() * inv_n;  // sigma_src^2
    result.s = d.dot(reflection_fix) / variance_src;                // trace(D S) / sigma_src^2
  }
  result.t = mean_dst - result.s * result.R * mean_src;
  return result;
}

double rotationUncertaintyDeg(const Eigen::Matrix3Xd& positions, double residual_rms_m) {
  if (positions.cols() == 0) return 90.0;
  const Eigen::Matrix3Xd centred = positions.colwise() - positions.rowwise().mean();
  const Eigen::Vector3d extent = principalExtents(centred);
  const double lever_m = std::hypot(extent(1), extent(2));
  return std::atan2(residual_rms_m, lever_m) * 180.0 / std::numbers::pi;
}

Sim3d alignPositions(const Eigen::Matrix3Xd& est_positions, const Eigen::Matrix3Xd& gt_positions,
                     AlignmentMode mode, int first_n) {
  if (est_positions.cols() != gt_positions.cols()) {
    throw InputError(fmt::format("cannot align {} estimate positions to {} ground-truth positions",
                                 est_positions.cols(), gt_positions.cols()));
  }
  if (mode == AlignmentMode::kNone) return Sim3d{};
  const Eigen::Index used = (first_n > 0 && first_n < est_positions.cols())
                                ? static_cast<Eigen::Index>(first_n)
                                : est_positions.cols();
  return umeyamaAlignment(est_positions.leftCols(used), gt_positions.leftCols(used),
                          mode == AlignmentMode::kSim3);
}

}  // namespace superdyna::eval

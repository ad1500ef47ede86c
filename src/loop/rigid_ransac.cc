#include "superdyna/loop/rigid_ransac.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <cmath>
#include <random>
#include <stdexcept>

#include "superdyna/core/error.h"

namespace superdyna::loop {

void RigidRansacOptions::validate() const {
  if (iterations < 1) throw OptionError("loop.ransac_iterations", "must be >= 1");
  if (min_inliers < 3) throw OptionError("loop.ransac_min_inliers", "must be >= 3");
  if (seed < 0) throw OptionError("loop.ransac_seed", "must be >= 0");
}

namespace {

/// A fitted transform: a ~= scale * T.rotation() * b + T.t.
struct Fit {
  SE3d T;
  double scale = 1.0;
};

/// Umeyama over the flagged correspondences, with or without the scale.
std::optional<Fit> fitTransform(const std::vector<Eigen::Vector3d>& a,
                                const std::vector<Eigen::Vector3d>& b, const std::vector<bool>& use,
                                bool with_scale) {
  std::vector<std::size_t> chosen;
  for (std::size_t i = 0; i < a.size() && i < b.size(); ++i)
    if (use.empty() || use[i]) chosen.push_back(i);
  if (chosen.size() < 3) return std::nullopt;
  Eigen::Matrix3Xd from(3, static_cast<Eigen::Index>(chosen.size()));
  Eigen::Matrix3Xd to(3, static_cast<Eigen::Index>(chosen.size()));
  for (std::size_t k = 0; k < chosen.size(); ++k) {
    from.col(static_cast<Eigen::Index>(k)) = b[chosen[k]];
    to.col(static_cast<Eigen::Index>(k)) = a[chosen[k]];
  }
  // Degenerate: all points (nearly) on a line give no unique rotation.
  const Eigen::Matrix3Xd centred = from.colwise() - from.rowwise().mean();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(centred * centred.transpose());
  const Eigen::Vector3d singular = svd.singularValues();
  if (!(singular(1) > 1e-12 * std::max(1.0, singular(0)))) return std::nullopt;
  const Eigen::Matrix4d M = Eigen::umeyama(from, to, with_scale);
  if (!M.allFinite()) return std::nullopt;
  // With the scale, M's upper-left block is s * R.
  const double scale = with_scale ? std::cbrt(M.topLeftCorner<3, 3>().determinant()) : 1.0;
  if (!(scale > 0.0)) return std::nullopt;
  if (!with_scale) return Fit{SE3d::fromMatrix(M), 1.0};
  Eigen::Matrix4d unscaled = M;
  unscaled.topLeftCorner<3, 3>() /= scale;
  return Fit{SE3d::fromMatrix(unscaled), scale};
}

std::optional<RigidRansacResult> ransac(
    const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
    const std::function<bool(const SE3d& T_a_b, std::size_t i)>& is_inlier,
    const RigidRansacOptions& options, bool with_scale) {
  options.validate();
  if (a.size() != b.size()) throw std::invalid_argument("ransacRigid: a and b differ in size");
  const std::size_t n = a.size();
  if (n < 3 || static_cast<int>(n) < options.min_inliers) return std::nullopt;
  std::mt19937 rng(static_cast<unsigned>(options.seed));
  const auto classify = [&](const Fit& fit, std::vector<bool>& flags) {
    int count = 0;
    flags.assign(n, false);
    for (std::size_t i = 0; i < n; ++i) {
      flags[i] = is_inlier(fit.T, i);
      count += flags[i] ? 1 : 0;
    }
    return count;
  };
  RigidRansacResult best;
  std::vector<bool> flags;
  std::vector<bool> sample(n, false);
  const auto keep = [&](const Fit& fit, int count) {
    best.num_inliers = count;
    best.T_a_b = fit.T;
    best.scale = fit.scale;
    best.inliers = flags;
  };
  for (int it = 0; it < options.iterations; ++it) {
    std::size_t picks[3];
    for (int k = 0; k < 3; ++k) {
      bool repeated = true;
      while (repeated) {
        picks[k] = static_cast<std::size_t>(rng() % n);
        repeated = false;
        for (int j = 0; j < k; ++j)
          repeated = repeated || picks[j] == picks[k];
      }
    }
    std::fill(sample.begin(), sample.end(), false);
    for (const std::size_t p : picks)
      sample[p] = true;
    const std::optional<Fit> fit = fitTransform(a, b, sample, with_scale);
    if (!fit) continue;
    const int count = classify(*fit, flags);
    if (count > best.num_inliers) keep(*fit, count);
  }
  if (best.num_inliers < options.min_inliers) return std::nullopt;
  // Refit on the inliers while that does not lose any.
  for (int round = 0; round < 3; ++round) {
    const std::optional<Fit> fit = fitTransform(a, b, best.inliers, with_scale);
    if (!fit) break;
    const int count = classify(*fit, flags);
    if (count < best.num_inliers) break;
    keep(*fit, count);
  }
  return best;
}

}  // namespace

std::optional<SE3d> fitRigid(const std::vector<Eigen::Vector3d>& a,
                             const std::vector<Eigen::Vector3d>& b, const std::vector<bool>& use) {
  const std::optional<Fit> fit = fitTransform(a, b, use, false);
  if (!fit) return std::nullopt;
  return fit->T;
}

std::optional<Sim3d> fitSimilarity(const std::vector<Eigen::Vector3d>& a,
                                   const std::vector<Eigen::Vector3d>& b,
                                   const std::vector<bool>& use) {
  const std::optional<Fit> fit = fitTransform(a, b, use, true);
  if (!fit) return std::nullopt;
  return Sim3d::fromSE3(fit->T, fit->scale);
}

std::optional<RigidRansacResult> ransacRigid(
    const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
    const std::function<bool(const SE3d& T_a_b, std::size_t i)>& is_inlier,
    const RigidRansacOptions& options) {
  return ransac(a, b, is_inlier, options, false);
}

std::optional<RigidRansacResult> ransacSimilarity(
    const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
    const std::function<bool(const SE3d& T_a_b, std::size_t i)>& is_inlier,
    const RigidRansacOptions& options) {
  return ransac(a, b, is_inlier, options, true);
}

}  // namespace superdyna::loop

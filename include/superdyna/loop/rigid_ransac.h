#pragma once
// RANSAC for the rigid transform between two sets of corresponding 3D points (SE(3), no scale):
// minimal samples of three correspondences solved in closed form (Umeyama / Horn, Eigen::umeyama),
// inliers by a caller-given test, refit on all inliers of the best hypothesis.

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <vector>

#include "superdyna/core/geometry.h"

namespace superdyna::loop {

struct RigidRansacOptions {
  int iterations = 300;  ///< Hypotheses tried, >= 1.
  int min_inliers = 12;  ///< Fewer inliers for the best hypothesis = no result, >= 3.
  int seed = 7;          ///< Of the sample generator, >= 0: same input, same result.
  /// Throws OptionError naming the first invalid field (prefix "loop.ransac_").
  void validate() const;
  bool operator==(const RigidRansacOptions&) const = default;
};

struct RigidRansacResult {
  SE3d T_a_b;                 ///< a[i] ~= T_a_b * b[i] for the inliers.
  std::vector<bool> inliers;  ///< Per correspondence.
  int num_inliers = 0;
};

/// Least-squares rigid transform T with a[i] ~= T * b[i] over the flagged correspondences (all
/// when `use` is empty); nullopt with fewer than three or a degenerate (collinear) set.
std::optional<SE3d> fitRigid(const std::vector<Eigen::Vector3d>& a,
                             const std::vector<Eigen::Vector3d>& b,
                             const std::vector<bool>& use = {});

/// is_inlier(T, i): whether correspondence i agrees with the hypothesis T_a_b (e.g. a
/// reprojection error bound). nullopt when no hypothesis reaches options.min_inliers. Throws
/// std::invalid_argument when a and b differ in size.
std::optional<RigidRansacResult> ransacRigid(
    const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
    const std::function<bool(const SE3d& T_a_b, std::size_t i)>& is_inlier,
    const RigidRansacOptions& options = {});

}  // namespace superdyna::loop

#pragma once
// RANSAC for the rigid transform between two sets of corresponding 3D points (SE(3)), or for the
// similarity (Sim(3): with a scale, for monocular maps, whose scale drifts): minimal samples of
// three correspondences solved in closed form (Umeyama / Horn, Eigen::umeyama), inliers by a
// caller-given test, refit on all inliers of the best hypothesis.

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
  SE3d T_a_b;                 ///< a[i] ~= T_a_b * b[i] for the inliers (rigid) ...
  double scale = 1.0;         ///< ... a[i] ~= scale * R_a_b * b[i] + t_a_b (similarity).
  std::vector<bool> inliers;  ///< Per correspondence.
  int num_inliers = 0;
};

/// Least-squares rigid transform T with a[i] ~= T * b[i] over the flagged correspondences (all
/// when `use` is empty); nullopt with fewer than three or a degenerate (collinear) set.
std::optional<SE3d> fitRigid(const std::vector<Eigen::Vector3d>& a,
                             const std::vector<Eigen::Vector3d>& b,
                             const std::vector<bool>& use = {});

/// Least-squares similarity S with a[i] ~= S * b[i] over the flagged correspondences; nullopt as
/// fitRigid, or when the points of b all coincide.
std::optional<Sim3d> fitSimilarity(const std::vector<Eigen::Vector3d>& a,
                                   const std::vector<Eigen::Vector3d>& b,
                                   const std::vector<bool>& use = {});

/// is_inlier(T, i): whether correspondence i agrees with the hypothesis T_a_b (e.g. a
/// reprojection error bound). nullopt when no hypothesis reaches options.min_inliers. Throws
/// std::invalid_argument when a and b differ in size.
std::optional<RigidRansacResult> ransacRigid(
    const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
    const std::function<bool(const SE3d& T_a_b, std::size_t i)>& is_inlier,
    const RigidRansacOptions& options = {});

/// As ransacRigid, for the similarity a[i] ~= s * R * b[i] + t; is_inlier sees its rotation and
/// translation (R, t) as T_a_b: a test that projects a-points into the frame of b (a camera) is
/// blind to the scale, which only stretches b's points along their rays.
std::optional<RigidRansacResult> ransacSimilarity(
    const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
    const std::function<bool(const SE3d& T_a_b, std::size_t i)>& is_inlier,
    const RigidRansacOptions& options = {});

}  // namespace superdyna::loop

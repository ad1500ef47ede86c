#pragma once
// Dense Levenberg-Marquardt over one pose (motion-only bundle adjustment's solver).
//
// The residuals are the same Ceres cost functions the bundle adjustments use (on a pose block of
// SE3Manifold's convention, se3_manifold.h, and optionally a constant point); only the solver is
// our own. With six unknowns the solve itself is a 6x6 system, and a ceres::Problem costs more to
// build and hand over than that system costs to solve (measured: `superdyna_bench
// --benchmark_filter=PoseOptimizer`), while tracking solves it several times per frame. Basalt
// and ORB-SLAM (through g2o) solve their motion-only problems with a dense solver of this kind.
//
// The cost is sum_i rho_i(|r_i|^2) with Ceres' HuberLoss (rho(s) = s up to delta^2, then
// 2 delta sqrt(s) - delta^2) or none; the normal equations weight each residual by rho'(s)
// (iteratively reweighted least squares), and steps are taken in SE3Manifold's tangent
// [dq, dp] (plusPose), so the minimum is the one Ceres finds for the same problem.

#include <ceres/cost_function.h>

#include <optional>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/optim/se3_manifold.h"

namespace superdyna::optim {

inline constexpr int kMaxPoseTermResiduals = 6;  ///< The largest cost function PoseTerm takes.

/// One residual block: a cost function on [pose (7), point (3)] with the constant point, or on
/// [pose (7)] alone (point = nullptr), with its Huber threshold on the residual norm (0: no loss).
struct PoseTerm {
  const ceres::CostFunction* factor = nullptr;  ///< Not owned; at most kMaxPoseTermResiduals.
  const double* point = nullptr;                ///< Not owned; 3 doubles, held constant.
  double huber_delta = 0.0;
};

struct PoseLeastSquaresOptions {
  int max_iterations = 10;            ///< Linear solves, rejected steps included (as Ceres counts).
  double function_tolerance = 1e-6;   ///< Stop when the cost falls by less than this share.
  double parameter_tolerance = 1e-8;  ///< Stop when the step is shorter than this [tangent units].
  double gradient_tolerance = 1e-10;  ///< Stop when the gradient's largest entry is below this.
  double initial_lambda = 1e-4;       ///< Damping of the first step (Ceres: 1 / trust radius).
};

class PoseLeastSquares {
 public:
  /// The terms and the points they name must outlive the object.
  explicit PoseLeastSquares(std::vector<PoseTerm> terms, PoseLeastSquaresOptions options = {});

  /// The pose minimising the cost from `start`. Steps that would leave a residual unevaluable
  /// (a point moving behind the camera) are rejected like steps that raise the cost; when a
  /// residual cannot be evaluated at `start`, `start` is returned.
  SE3d solve(const SE3d& start) const;

  /// The robustified cost at T_w_b; nullopt when a residual cannot be evaluated there.
  std::optional<double> cost(const SE3d& T_w_b) const;

 private:
  struct NormalEquations;
  std::optional<NormalEquations> linearize(const SE3d& T_w_b) const;
  /// Adds one term of `Rows` residuals (Eigen::Dynamic: any up to kMaxPoseTermResiduals) at the
  /// pose block to the normal equations; false when it cannot be evaluated there.
  template <int Rows>
  static bool accumulate(const PoseTerm& term, const PoseBlock& block,
                         const Eigen::Matrix<double, kPoseBlockSize, kPoseTangentSize>& plus,
                         NormalEquations& equations);

  std::vector<PoseTerm> terms_;
  PoseLeastSquaresOptions options_;
};

}  // namespace superdyna::optim

#pragma once
// The Ceres solver settings every estimator of the back end shares: one thread (deterministic
// runs are bit-identical: Ceres' multi-threaded Jacobian evaluation sums in varying order) and
// no logging; the caller picks the linear solver for its problem's structure.

#include <ceres/solver.h>

namespace superdyna::optim {

inline ceres::Solver::Options quietSolverOptions(ceres::LinearSolverType linear_solver,
                                                 int max_iterations) {
  ceres::Solver::Options options;
  options.linear_solver_type = linear_solver;
  options.max_num_iterations = max_iterations;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  options.minimizer_progress_to_stdout = false;
  return options;
}

}  // namespace superdyna::optim

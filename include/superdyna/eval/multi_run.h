#pragma once
// Several runs of one system on one sequence (SLAM is not deterministic: threads, RANSAC). Papers
// report the median or the mean over runs; the mean with a 95 % Student-t confidence interval
// tells whether two systems differ by more than run-to-run noise.

#include <cstddef>
#include <string>
#include <vector>

#include "superdyna/eval/evaluate.h"

namespace superdyna::eval {

/// Spread of one metric over runs, in the metric's unit.
struct RunStatistics {
  std::size_t runs = 0;
  double median = 0.0;
  double mean = 0.0;
  double std = 0.0;             ///< Sample standard deviation (n - 1); NaN for one run.
  double ci95_halfwidth = 0.0;  ///< t_{0.975, n-1} * std / sqrt(n); NaN for one run.
};

/// Median, mean, sample std and 95 % half-width of `values`; throws InputError when empty.
RunStatistics summarizeRunValues(const std::vector<double>& values);

struct NamedRun {
  std::string name;  ///< E.g. the estimate's file name.
  EvaluationResult result;
};

struct MultiRunResult {
  std::vector<NamedRun> runs;
  RunStatistics ate_rmse;  ///< Over the runs' ATE RMSE [m].
  /// Over the RPE translation RMSE of the runs that have an RPE (unit of the RPE delta); `runs`
  /// 0 and NaN values when none has (paths shorter than the delta).
  RunStatistics rpe_trans;
  RunStatistics rpe_rot;  ///< Over the runs' RPE rotation RMSE, as rpe_trans.
};

/// Summarises already evaluated runs; throws InputError when `runs` is empty.
MultiRunResult summarizeRuns(std::vector<NamedRun> runs);

/// Evaluates every estimate against `gt` with the same options and summarises. `names` may be
/// empty (runs are then called "run 1", "run 2", ...) or give one name per estimate.
MultiRunResult evaluateRuns(const Trajectory& gt, const std::vector<Trajectory>& estimates,
                            const EvaluationOptions& options,
                            const std::vector<std::string>& names = {});

}  // namespace superdyna::eval

#include "superdyna/eval/multi_run.h"

#include <fmt/format.h>

#include <limits>

#include "superdyna/core/error.h"

namespace superdyna::eval {
namespace {

/// One value per run, picked by `metric`.
template <typename Metric>
std::vector<double> collect(const std::vector<NamedRun>& runs, Metric metric) {
  std::vector<double> values;
  values.reserve(runs.size());
  for (const NamedRun& run : runs)
    values.push_back(metric(run.result));
  return values;
}

/// The RPE of the runs that have one (a path shorter than the delta has none: require_rpe false);
/// no runs, no statistics (RunStatistics::runs 0, values NaN).
template <typename Metric>
RunStatistics summarizeRpe(const std::vector<NamedRun>& runs, Metric metric) {
  std::vector<double> values;
  for (const NamedRun& run : runs)
    if (run.result.rpe_missing.empty()) values.push_back(metric(run.result));
  if (!values.empty()) return summarizeRunValues(values);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  return {0, nan, nan, nan, nan};
}

}  // namespace

RunStatistics summarizeRunValues(const std::vector<double>& values) {
  if (values.empty()) throw InputError("cannot summarise zero runs");
  const ErrorStatistics stats = computeStatistics(values);
  RunStatistics summary;
  summary.runs = values.size();
  summary.median = stats.median;
  summary.mean = stats.mean;
  summary.std = sampleStandardDeviation(values);
  summary.ci95_halfwidth = confidenceHalfWidth(values, 0.95);
  return summary;
}

MultiRunResult summarizeRuns(std::vector<NamedRun> runs) {
  if (runs.empty()) throw InputError("cannot summarise zero runs");
  MultiRunResult result;
  result.ate_rmse =
      summarizeRunValues(collect(runs, [](const EvaluationResult& r) { return r.ate_trans.rmse; }));
  result.rpe_trans = summarizeRpe(runs, [](const EvaluationResult& r) { return r.rpe_trans.rmse; });
  result.rpe_rot = summarizeRpe(runs, [](const EvaluationResult& r) { return r.rpe_rot.rmse; });
  result.runs = std::move(runs);
  return result;
}

MultiRunResult evaluateRuns(const Trajectory& gt, const std::vector<Trajectory>& estimates,
                            const EvaluationOptions& options,
                            const std::vector<std::string>& names) {
  if (!names.empty() && names.size() != estimates.size()) {
    throw OptionError("names",
                      fmt::format("got {} names for {} estimates", names.size(), estimates.size()));
  }
  std::vector<NamedRun> runs;
  for (std::size_t k = 0; k < estimates.size(); ++k) {
    const std::string name = names.empty() ? fmt::format("run {}", k + 1) : names[k];
    try {
      runs.push_back({name, evaluate(gt, estimates[k], options)});
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: {}", name, e.what()));  // say which run failed
    }
  }
  return summarizeRuns(std::move(runs));
}

}  // namespace superdyna::eval

#include "superdyna/eval/report_table.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace superdyna::eval {
namespace {

constexpr int kLabelWidth = 18;
constexpr int kStatWidth = 12;
constexpr int kRunMetricWidth = 22;

std::string statisticsRow(const std::string& label, const ErrorStatistics& s) {
  return fmt::format("{:<{}}{:>{}.6f}{:>{}.6f}{:>{}.6f}{:>{}.6f}{:>{}.6f}{:>{}.6f}\n", label,
                     kLabelWidth, s.rmse, kStatWidth, s.mean, kStatWidth, s.median, kStatWidth,
                     s.std, kStatWidth, s.min, kStatWidth, s.max, kStatWidth);
}

/// A row of "n/a" for a metric that was not computed.
std::string missingRow(const std::string& label) {
  return fmt::format("{:<{}}{:>{}}{:>{}}{:>{}}{:>{}}{:>{}}{:>{}}\n", label, kLabelWidth, "n/a",
                     kStatWidth, "n/a", kStatWidth, "n/a", kStatWidth, "n/a", kStatWidth, "n/a",
                     kStatWidth, "n/a", kStatWidth);
}

/// "no pose pair is 1 m apart ..." of "RPE: no pose pair is 1 m apart ...".
std::string withoutRpePrefix(const std::string& reason) {
  const std::string prefix = "RPE: ";
  return reason.starts_with(prefix) ? reason.substr(prefix.size()) : reason;
}

std::string rpeDescription(const EvaluationResult& result) {
  if (!result.rpe_missing.empty())
    return "not computed (" + withoutRpePrefix(result.rpe_missing) + ")";
  return fmt::format("delta {} {}, {} pairs", result.rpe_options.delta,
                     toString(result.rpe_options.unit), result.rpe_trans.count);
}

/// The RMSE of a run's RPE, or "n/a" when the run has none.
std::string rpeCell(const EvaluationResult& result, double rmse) {
  return result.rpe_missing.empty() ? fmt::format("{:.6f}", rmse) : std::string("n/a");
}

std::string alignmentDescription(const EvaluationResult& result) {
  if (result.alignment_given) return fmt::format("given, scale {:.6f}", result.scale());
  if (result.align == AlignmentMode::kNone) return "none";
  const std::string over =
      result.align_first_n > 0 && result.align_first_n < static_cast<int>(result.pairs)
          ? fmt::format("first {} pairs", result.align_first_n)
          : std::string("all pairs");
  const std::string rotation =
      result.alignmentRotationUndetermined()
          ? fmt::format(
                "; rotation NOT determined by this path (uncertain by about {:.0f} deg): "
                "ATE rot is not meaningful",
                result.alignment_rotation_uncertainty_deg)
          : std::string();
  return fmt::format("{} over {}, scale {:.6f}{}", toString(result.align), over, result.scale(),
                     rotation);
}

/// "0.012345 ± 0.000123", or "0.012345 ± n/a" when the interval is undefined (one run), or "n/a"
/// when no run has the metric.
std::string meanWithInterval(const RunStatistics& s) {
  if (s.runs == 0) return "n/a";
  if (!std::isfinite(s.ci95_halfwidth)) return fmt::format("{:.6f} ± n/a", s.mean);
  return fmt::format("{:.6f} ± {:.6f}", s.mean, s.ci95_halfwidth);
}

/// The median over runs, or "n/a" when no run has the metric.
std::string medianCell(const RunStatistics& s) {
  return s.runs == 0 ? std::string("n/a") : fmt::format("{:.6f}", s.median);
}

std::size_t nameWidth(const MultiRunResult& result) {
  std::size_t width = std::string("mean ± 95% CI").size();
  for (const NamedRun& run : result.runs)
    width = std::max(width, run.name.size());
  return width + 2;
}

}  // namespace

std::string formatTable(const EvaluationResult& result) {
  const DeltaUnit unit = result.rpe_options.unit;
  std::string out;
  out += fmt::format("Pose pairs: {} (ground truth {} poses, estimate {} poses)\n", result.pairs,
                     result.gt_poses, result.est_poses);
  out += fmt::format("Alignment:  {}\n", alignmentDescription(result));
  out += fmt::format("RPE:        {}\n\n", rpeDescription(result));
  out += fmt::format("{:<{}}{:>{}}{:>{}}{:>{}}{:>{}}{:>{}}{:>{}}\n", "metric", kLabelWidth, "rmse",
                     kStatWidth, "mean", kStatWidth, "median", kStatWidth, "std", kStatWidth, "min",
                     kStatWidth, "max", kStatWidth);
  out += statisticsRow("ATE trans [m]", result.ate_trans);
  out += statisticsRow("ATE rot [deg]", result.ate_rot);
  const std::string rpe_trans = fmt::format("RPE trans [{}]", rpeTransUnit(unit));
  const std::string rpe_rot = fmt::format("RPE rot [{}]", rpeRotUnit(unit));
  if (!result.rpe_missing.empty()) return out + missingRow(rpe_trans) + missingRow(rpe_rot);
  out += statisticsRow(rpe_trans, result.rpe_trans);
  out += statisticsRow(rpe_rot, result.rpe_rot);
  return out;
}

std::string formatTable(const MultiRunResult& result) {
  const DeltaUnit unit =
      result.runs.empty() ? DeltaUnit::kMeters : result.runs.front().result.rpe_options.unit;
  const std::size_t name_width = nameWidth(result);
  std::string out = fmt::format("{:<{}}{:>8}{:>11}{:>{}}{:>{}}{:>{}}\n", "run", name_width, "pairs",
                                "scale", "ATE RMSE [m]", kRunMetricWidth,
                                fmt::format("RPE trans [{}]", rpeTransUnit(unit)), kRunMetricWidth,
                                fmt::format("RPE rot [{}]", rpeRotUnit(unit)), kRunMetricWidth);
  for (const NamedRun& run : result.runs) {
    const EvaluationResult& r = run.result;
    out += fmt::format("{:<{}}{:>8}{:>11.6f}{:>{}.6f}{:>{}}{:>{}}\n", run.name, name_width, r.pairs,
                       r.scale(), r.ate_trans.rmse, kRunMetricWidth, rpeCell(r, r.rpe_trans.rmse),
                       kRunMetricWidth, rpeCell(r, r.rpe_rot.rmse), kRunMetricWidth);
  }
  out += fmt::format("{:<{}}{:>19}{:>{}.6f}{:>{}}{:>{}}\n", "median", name_width, "",
                     result.ate_rmse.median, kRunMetricWidth, medianCell(result.rpe_trans),
                     kRunMetricWidth, medianCell(result.rpe_rot), kRunMetricWidth);
  out += fmt::format("{:<{}}{:>19}{:>{}}{:>{}}{:>{}}\n", "mean ± 95% CI", name_width, "",
                     meanWithInterval(result.ate_rmse), kRunMetricWidth,
                     meanWithInterval(result.rpe_trans), kRunMetricWidth,
                     meanWithInterval(result.rpe_rot), kRunMetricWidth);
  return out;
}

}  // namespace superdyna::eval

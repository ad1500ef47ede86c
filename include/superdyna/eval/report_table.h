#pragma once
// Human-readable fixed-width tables for the terminal.

#include <string>

#include "superdyna/eval/evaluate.h"
#include "superdyna/eval/multi_run.h"

namespace superdyna::eval {

/// A header line (pairs, alignment, scale) and one row per metric (ATE trans [m], ATE rot [deg],
/// RPE trans, RPE rot) with columns rmse, mean, median, std, min, max. Ends with a newline.
std::string formatTable(const EvaluationResult& result);

/// One row per run (name, pairs, scale, ATE RMSE, RPE trans, RPE rot), then the median row and the
/// "mean ± 95 % CI half-width" row. Ends with a newline.
std::string formatTable(const MultiRunResult& result);

}  // namespace superdyna::eval

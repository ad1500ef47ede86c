#pragma once
// Machine-readable results (JSON) for scripts that build the paper tables. Every error value is in
// the unit stated by its key or by the rpe_unit_* keys; NaN (e.g. the interval of a single run)
// is written as null.

#include <filesystem>
#include <nlohmann/json.hpp>

#include "superdyna/eval/evaluate.h"
#include "superdyna/eval/multi_run.h"

namespace superdyna::eval {

/// One run: ate_rmse, ate_mean, ate_median, ate_std, ate_min, ate_max [m]; ate_rot_rmse_deg,
/// ate_rot_mean_deg; scale; pairs; gt_poses; est_poses;
/// alignment {mode, R (3 rows of 3), t [m], s, first_n}; rpe_trans, rpe_trans_mean, rpe_rot,
/// rpe_rot_mean (rpe_trans / rpe_rot are RMSEs); rpe_pairs, rpe_delta, rpe_delta_unit,
/// rpe_unit_trans, rpe_unit_rot; without an RPE (EvaluationResult::rpe_missing) its values are
/// null and rpe_missing says why.
nlohmann::json toJson(const EvaluationResult& result);

/// {runs: [toJson(run) + {name}], summary: {runs, ate_rmse_median, ate_rmse_mean, ate_rmse_std,
/// ate_rmse_ci95_halfwidth, rpe_trans_median, rpe_trans_mean, rpe_trans_ci95_halfwidth,
/// rpe_rot_median, rpe_rot_mean, rpe_rot_ci95_halfwidth, rpe_unit_trans, rpe_unit_rot}}.
nlohmann::json toJson(const MultiRunResult& result);

/// The alignment (R, t, s) of a report written by toJson (one run, or a multi-run report of one
/// run): the `alignment` object. InputError naming the file and field when missing or malformed,
/// or when R is no rotation.
Sim3d readAlignmentJson(const std::filesystem::path& file);

}  // namespace superdyna::eval

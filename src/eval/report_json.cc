#include "superdyna/eval/report_json.h"

#include <cmath>
#include <fstream>

#include "superdyna/core/error.h"

namespace superdyna::eval {
namespace {

/// JSON has no NaN; undefined values (one run has no spread) become null.
nlohmann::json numberOrNull(double value) {
  if (std::isfinite(value)) return value;
  return nullptr;
}

nlohmann::json alignmentJson(const EvaluationResult& result) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) {
    rows.push_back({result.alignment.R(r, 0), result.alignment.R(r, 1), result.alignment.R(r, 2)});
  }
  const Eigen::Vector3d& t = result.alignment.t;
  return {{"mode", result.alignment_given ? std::string("given") : toString(result.align)},
          {"R", rows},
          {"t", {t.x(), t.y(), t.z()}},
          {"s", result.alignment.s},
          {"first_n", result.align_first_n},
          {"rotation_uncertainty_deg", result.alignment_rotation_uncertainty_deg},
          {"rotation_determined", !result.alignmentRotationUndetermined()}};
}

}  // namespace

nlohmann::json toJson(const EvaluationResult& result) {
  const DeltaUnit unit = result.rpe_options.unit;
  nlohmann::json json = {
      {"ate_rmse", result.ate_trans.rmse},
      {"ate_mean", result.ate_trans.mean},
      {"ate_median", result.ate_trans.median},
      {"ate_std", result.ate_trans.std},
      {"ate_min", result.ate_trans.min},
      {"ate_max", result.ate_trans.max},
      {"ate_rot_rmse_deg", result.ate_rot.rmse},
      {"ate_rot_mean_deg", result.ate_rot.mean},
      {"ate_rot_median_deg", result.ate_rot.median},
      {"ate_rot_max_deg", result.ate_rot.max},
      {"scale", result.scale()},
      {"pairs", result.pairs},
      {"gt_poses", result.gt_poses},
      {"est_poses", result.est_poses},
      {"alignment", alignmentJson(result)},
      {"rpe_trans", result.rpe_trans.rmse},
      {"rpe_trans_mean", result.rpe_trans.mean},
      {"rpe_trans_median", result.rpe_trans.median},
      {"rpe_rot", result.rpe_rot.rmse},
      {"rpe_rot_mean", result.rpe_rot.mean},
      {"rpe_rot_median", result.rpe_rot.median},
      {"rpe_pairs", result.rpe_trans.count},
      {"rpe_delta", result.rpe_options.delta},
      {"rpe_delta_unit", toString(unit)},
      {"rpe_unit_trans", rpeTransUnit(unit)},
      {"rpe_unit_rot", rpeRotUnit(unit)},
  };
  // RPE values of a path shorter than the delta are null, with the reason.
  if (!result.rpe_missing.empty()) {
    for (const char* key : {"rpe_trans", "rpe_trans_mean", "rpe_trans_median", "rpe_rot",
                            "rpe_rot_mean", "rpe_rot_median"}) {
      json[key] = nullptr;
    }
    json["rpe_missing"] = result.rpe_missing;
  }
  return json;
}

nlohmann::json toJson(const MultiRunResult& result) {
  nlohmann::json runs = nlohmann::json::array();
  for (const NamedRun& run : result.runs) {
    nlohmann::json entry = toJson(run.result);
    entry["name"] = run.name;
    runs.push_back(std::move(entry));
  }
  const DeltaUnit unit =
      result.runs.empty() ? DeltaUnit::kMeters : result.runs.front().result.rpe_options.unit;
  const nlohmann::json summary = {
      {"runs", result.runs.size()},
      {"ate_rmse_median", numberOrNull(result.ate_rmse.median)},
      {"ate_rmse_mean", numberOrNull(result.ate_rmse.mean)},
      {"ate_rmse_std", numberOrNull(result.ate_rmse.std)},
      {"ate_rmse_ci95_halfwidth", numberOrNull(result.ate_rmse.ci95_halfwidth)},
      {"rpe_trans_median", numberOrNull(result.rpe_trans.median)},
      {"rpe_trans_mean", numberOrNull(result.rpe_trans.mean)},
      {"rpe_trans_ci95_halfwidth", numberOrNull(result.rpe_trans.ci95_halfwidth)},
      {"rpe_rot_median", numberOrNull(result.rpe_rot.median)},
      {"rpe_rot_mean", numberOrNull(result.rpe_rot.mean)},
      {"rpe_rot_ci95_halfwidth", numberOrNull(result.rpe_rot.ci95_halfwidth)},
      {"rpe_unit_trans", rpeTransUnit(unit)},
      {"rpe_unit_rot", rpeRotUnit(unit)},
  };
  return {{"runs", runs}, {"summary", summary}};
}

Sim3d readAlignmentJson(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(InputLocation(file), "cannot open the alignment file");
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(InputLocation(file), std::string("not JSON: ") + e.what());
  }
  if (json.contains("runs")) {
    if (!json["runs"].is_array() || json["runs"].size() != 1)
      throw InputError(InputLocation(file, 0, "runs"),
                       "an alignment needs a report of exactly one run");
    json = json["runs"][0];
  }
  if (!json.contains("alignment") || !json["alignment"].is_object())
    throw InputError(InputLocation(file, 0, "alignment"),
                     "no 'alignment' object (write one with superdyna eval --json)");
  const nlohmann::json& a = json["alignment"];
  Sim3d alignment;
  try {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        alignment.R(r, c) =
            a.at("R").at(static_cast<std::size_t>(r)).at(static_cast<std::size_t>(c)).get<double>();
    for (int k = 0; k < 3; ++k)
      alignment.t[k] = a.at("t").at(static_cast<std::size_t>(k)).get<double>();
    alignment.s = a.at("s").get<double>();
  } catch (const nlohmann::json::exception& e) {
    throw InputError(InputLocation(file, 0, "alignment"), std::string("malformed: ") + e.what());
  }
  const double orthonormality =
      (alignment.R * alignment.R.transpose() - Eigen::Matrix3d::Identity()).norm();
  if (!alignment.R.allFinite() || !alignment.t.allFinite() || !(orthonormality < 1e-6) ||
      !(alignment.R.determinant() > 0.0) || !(alignment.s > 0.0) || !std::isfinite(alignment.s))
    throw InputError(InputLocation(file, 0, "alignment"),
                     "R must be a rotation, t finite and s positive");
  return alignment;
}

}  // namespace superdyna::eval

#include "superdyna/sweep/cell_result.h"

#include <fmt/format.h>

#include <cmath>
#include <fstream>

#include "superdyna/core/error.h"

namespace superdyna::sweep {

namespace {

/// JSON has no NaN: what was not measured is null.
nlohmann::json numberOrNull(double value) {
  if (std::isfinite(value)) return value;
  return nullptr;
}

double numberOrNaN(const nlohmann::json& json, const char* key, const std::filesystem::path& file) {
  if (!json.contains(key) || json[key].is_null()) return kNotMeasured;
  if (!json[key].is_number()) throw InputError(InputLocation(file, 0, key), "expected a number");
  return json[key].get<double>();
}

std::string textOrEmpty(const nlohmann::json& json, const char* key,
                        const std::filesystem::path& file) {
  if (!json.contains(key)) return {};
  if (!json[key].is_string()) throw InputError(InputLocation(file, 0, key), "expected a string");
  return json[key].get<std::string>();
}

}  // namespace

double CellResult::cpuMsPerFrame() const {
  return frames > 0 ? 1e3 * cpu_s / frames : kNotMeasured;
}

nlohmann::json toJson(const CellResult& r) {
  nlohmann::json stages = nlohmann::json::object();
  for (const auto& [stage, ms] : r.stage_ms)
    stages[stage] = numberOrNull(ms);
  return {{"sequence", r.sequence},
          {"config", r.config},
          {"run", r.run},
          {"cell_hash", r.cell_hash},
          {"ok", r.ok},
          {"error", r.error},
          {"ate_rmse_m", numberOrNull(r.ate_rmse_m)},
          {"ate_rot_deg", numberOrNull(r.ate_rot_deg)},
          {"rpe_trans", numberOrNull(r.rpe_trans)},
          {"rpe_rot", numberOrNull(r.rpe_rot)},
          {"rpe_trans_unit", r.rpe_trans_unit},
          {"rpe_rot_unit", r.rpe_rot_unit},
          {"frames", numberOrNull(r.frames)},
          {"lost_frames", numberOrNull(r.lost_frames)},
          {"map_resets", numberOrNull(r.map_resets)},
          {"fps", numberOrNull(r.fps)},
          {"stage_ms", stages},
          {"moving_precision", numberOrNull(r.moving_precision)},
          {"moving_recall", numberOrNull(r.moving_recall)},
          {"static_kept", numberOrNull(r.static_kept)},
          {"wall_s", numberOrNull(r.wall_s)},
          {"cpu_s", numberOrNull(r.cpu_s)},
          {"peak_rss_mb", numberOrNull(r.peak_rss_mb)}};
}

CellResult cellResultFromJson(const nlohmann::json& json, const std::filesystem::path& file) {
  if (!json.is_object()) throw InputError(InputLocation(file), "a cell result is a JSON object");
  CellResult r;
  r.sequence = textOrEmpty(json, "sequence", file);
  r.config = textOrEmpty(json, "config", file);
  if (r.sequence.empty() || r.config.empty()) {
    throw InputError(InputLocation(file, 0, "sequence"), "missing sequence or config name");
  }
  r.run = static_cast<int>(numberOrNaN(json, "run", file));
  r.cell_hash = textOrEmpty(json, "cell_hash", file);
  r.ok = json.value("ok", false);
  r.error = textOrEmpty(json, "error", file);
  r.ate_rmse_m = numberOrNaN(json, "ate_rmse_m", file);
  r.ate_rot_deg = numberOrNaN(json, "ate_rot_deg", file);
  r.rpe_trans = numberOrNaN(json, "rpe_trans", file);
  r.rpe_rot = numberOrNaN(json, "rpe_rot", file);
  r.rpe_trans_unit = textOrEmpty(json, "rpe_trans_unit", file);
  r.rpe_rot_unit = textOrEmpty(json, "rpe_rot_unit", file);
  r.frames = numberOrNaN(json, "frames", file);
  r.lost_frames = numberOrNaN(json, "lost_frames", file);
  r.map_resets = numberOrNaN(json, "map_resets", file);
  r.fps = numberOrNaN(json, "fps", file);
  if (json.contains("stage_ms") && json["stage_ms"].is_object()) {
    for (const auto& [stage, ms] : json["stage_ms"].items()) {
      r.stage_ms[stage] = ms.is_number() ? ms.get<double>() : kNotMeasured;
    }
  }
  r.moving_precision = numberOrNaN(json, "moving_precision", file);
  r.moving_recall = numberOrNaN(json, "moving_recall", file);
  r.static_kept = numberOrNaN(json, "static_kept", file);
  r.wall_s = numberOrNaN(json, "wall_s", file);
  r.cpu_s = numberOrNaN(json, "cpu_s", file);
  r.peak_rss_mb = numberOrNaN(json, "peak_rss_mb", file);
  return r;
}

CellResult readCellResult(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(InputLocation(file), "cannot read the cell result");
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(InputLocation(file), fmt::format("not valid JSON: {}", e.what()));
  }
  return cellResultFromJson(json, file);
}

}  // namespace superdyna::sweep

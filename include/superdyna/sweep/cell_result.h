#pragma once
// What one cell of a sweep (one sequence, one config, one run) measured: written by the cell as
// result.json (the last file it writes, so its presence marks a finished cell) and read back by
// the tables and the report.

#include <filesystem>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

namespace superdyna::sweep {

inline constexpr double kNotMeasured = std::numeric_limits<double>::quiet_NaN();

struct CellResult {
  std::string sequence;
  std::string config;
  int run = 1;
  std::string cell_hash;  ///< Of everything that defines the cell (command, config contents).
  bool ok = false;
  std::string error;  ///< Why the cell failed (exit status, evaluation error).
  // Accuracy (from the evaluation of the cell's trajectory).
  double ate_rmse_m = kNotMeasured;
  double ate_rot_deg = kNotMeasured;
  double rpe_trans = kNotMeasured;  ///< In rpe_trans_unit.
  double rpe_rot = kNotMeasured;    ///< In rpe_rot_unit.
  std::string rpe_trans_unit;
  std::string rpe_rot_unit;
  // The run's own numbers (superdyna run --stats; not for external systems).
  double frames = kNotMeasured;
  double lost_frames = kNotMeasured;
  double map_resets = kNotMeasured;
  double fps = kNotMeasured;
  std::map<std::string, double> stage_ms;  ///< Mean ms per frame by pipeline stage.
  // Moving-object decisions (cells with labelled keypoints on a simulated sequence: the run's
  // --dynamic-log scored against mav0/instance_states.csv, objects with >= 8 matched features).
  double moving_precision = kNotMeasured;
  double moving_recall = kNotMeasured;
  double static_kept = kNotMeasured;  ///< Share of the features on standing objects kept.
  // The process, measured by the sweep (wait4): every system alike.
  double wall_s = kNotMeasured;
  double cpu_s = kNotMeasured;  ///< User + system time of the process and its children.
  double peak_rss_mb = kNotMeasured;
  /// CPU time per frame, when the frames are known.
  double cpuMsPerFrame() const;
};

nlohmann::json toJson(const CellResult& result);
/// Throws InputError naming `file` when a field is missing or of the wrong type.
CellResult cellResultFromJson(const nlohmann::json& json, const std::filesystem::path& file);
CellResult readCellResult(const std::filesystem::path& file);

}  // namespace superdyna::sweep

#pragma once
// The tables of a sweep, in the forms papers print them, as Markdown (to read and paste) and CSV
// (to plot): accuracy per cell (ATE median, mean ± 95 % CI, RPE; Tables 1-9), one metric as a
// sequence x config matrix (ablation and mask perturbation tables, Tables 10-11, are such
// matrices with configs as rows), speed (FPS, CPU time, peak memory) and time per pipeline stage
// (Table 12). Accuracy tables hold only what a deterministic run reproduces bit for bit; times
// are in their own tables.

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "superdyna/sweep/cell_result.h"
#include "superdyna/sweep/spec.h"

namespace superdyna::sweep {

/// The runs of one (sequence, config) pair.
struct CellGroup {
  std::string sequence;
  std::string config;
  std::vector<CellResult> runs;  ///< Finished runs, ok or failed, in run order.
  std::vector<const CellResult*> ok() const;
};

/// A metric over a group's successful runs: its value (NaN when none) and its table text.
struct Metric {
  std::string name;
  std::string label;
  std::function<double(const CellGroup&)> value;
  std::function<std::string(const CellGroup&)> text;
};

/// ate_median, ate_mean_ci, ate_runs, rpe_trans_median, rpe_rot_median, lost_frames,
/// map_resets, fps, cpu_ms_per_frame, moving_precision, moving_recall, static_kept, peak_rss_mb.
const std::vector<Metric>& metrics();
const Metric& metric(const std::string& name);

/// Groups results by (sequence, config) in the spec's order; pairs without any result are
/// present with no runs (shown as "-").
std::vector<CellGroup> groupResults(const SweepSpec& spec, const std::vector<CellResult>& results);

struct TableText {
  std::string name;
  std::string title;
  std::string markdown;
  std::string csv;
};

/// Long form, one row per (sequence, config): runs, ATE median / mean ± CI / min / max, RPE,
/// lost frames, map resets.
TableText accuracyTable(const std::vector<CellGroup>& groups);
/// Precision and recall of "moving" and the features kept on standing objects, for the cells
/// that scored their moving-object decisions (the others are left out); none without such cells.
std::optional<TableText> decisionsTable(const std::vector<CellGroup>& groups);
/// FPS, CPU ms per frame and peak memory per (sequence, config).
TableText speedTable(const std::vector<CellGroup>& groups);
/// Mean ms per frame of each pipeline stage per config, over all its sequences and runs.
TableText timingTable(const SweepSpec& spec, const std::vector<CellGroup>& groups);
/// One metric as a matrix (TableSpec); the default sweep table is ATE median, sequences x configs.
TableText matrixTable(const SweepSpec& spec, const TableSpec& table,
                      const std::vector<CellGroup>& groups);

/// Every table: the ATE matrix, accuracy, decisions (when any cell scored them), the spec's
/// tables, speed and timing.
std::vector<TableText> allTables(const SweepSpec& spec, const std::vector<CellGroup>& groups);
/// Writes DIR/<name>.md and DIR/<name>.csv for each table and DIR/tables.md with all of them.
void writeTables(const std::vector<TableText>& tables, const std::filesystem::path& dir);

/// "0.78 cm" below a metre, "1.250 m" above: the unit papers use at each scale.
std::string formatMetres(double metres);

}  // namespace superdyna::sweep

#pragma once
// A sweep's tasks and what each does. Two kinds of task, each a unit any machine of a cluster
// can run on its own (`superdyna sweep SPEC --out DIR --task sequence:3`):
//   - a sequence: simulated once into DIR/sequences/<name> (recorded datasets need nothing);
//   - a cell (sequence, config, run): `superdyna run` (or an external command) into
//     DIR/cells/<sequence>/<config>/run-<k>, then scored with the evaluation of `superdyna eval`.
// Every task records its command line, the build's git revision, a hash of its definition and
// the machine; it writes its marker file last, so a task killed halfway is simply run again and
// a finished one (same definition) is never rerun.

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "superdyna/sweep/cell_result.h"
#include "superdyna/sweep/spec.h"

namespace superdyna::sweep {

struct SequenceTask {
  std::string name;
  std::filesystem::path dataset;      ///< The folder `run --path` reads.
  std::vector<std::string> simulate;  ///< The simulator's command; empty for a recorded dataset.
  std::filesystem::path marker;       ///< Written when the simulation finished.
  std::string hash;                   ///< Of the simulator's command.
  std::filesystem::path ground_truth;
  std::filesystem::path ground_truth_times;  ///< Empty when none.
};

struct CellTask {
  std::string sequence;
  std::string config;
  int run = 1;
  std::filesystem::path dir;
  std::string id() const;  ///< "sequence/config/run-k"
};

struct SweepPlan {
  std::filesystem::path out;
  /// Where the simulator and `superdyna run` start (relative paths in their arguments are the
  /// spec's); external commands start in their cell's folder.
  std::filesystem::path spec_dir;
  std::filesystem::path superdyna;  ///< The binary every task runs.
  std::vector<SequenceTask> sequences;
  std::vector<CellTask> cells;
  const SequenceTask& sequence(const std::string& name) const;
};

/// The tasks of `spec` writing under `out`, run with the `superdyna` binary.
SweepPlan planSweep(const SweepSpec& spec, const std::filesystem::path& out,
                    const std::filesystem::path& superdyna);

/// Whether a task still has to run: a simulated sequence without its marker (or with a marker of
/// another definition); a cell without result.json, or with one of another definition, or (with
/// `rerun_failed`) one that failed.
bool sequenceNeeded(const SequenceTask& task);
bool cellNeeded(const SweepSpec& spec, const SweepPlan& plan, const CellTask& cell,
                bool rerun_failed);

/// Simulates the sequence (clearing a half-written folder first). Throws InputError with the
/// log's tail when the simulator fails.
void prepareSequence(const SweepPlan& plan, const SequenceTask& task, const std::string& revision);

/// Runs and scores one cell; returns its result (also written as result.json, with cell.json,
/// command.txt, log.txt, the trajectory, stats.json, eval.json and pose_errors.csv). A failing
/// run or evaluation gives a result with ok = false; throws InputError only when the cell cannot
/// be attempted (its sequence not prepared, its folder not writable).
CellResult runCell(const SweepSpec& spec, const SweepPlan& plan, const CellTask& cell,
                   const std::string& revision);

/// The result.json of every finished cell of the plan, in plan order (results of another
/// definition of the cell, left by an earlier spec, are not part of this sweep).
std::vector<CellResult> collectResults(const SweepSpec& spec, const SweepPlan& plan);

/// The command of a cell as it runs (external configs: /bin/sh -c with the template filled in).
std::vector<std::string> cellCommand(const SweepSpec& spec, const SweepPlan& plan,
                                     const CellTask& cell);

/// The hash of a cell's definition: its command, its config file's contents, its sequence.
std::string cellHash(const SweepSpec& spec, const SweepPlan& plan, const CellTask& cell);

/// 64-bit FNV-1a as 16 hex digits: a stable fingerprint across machines and runs.
std::string fingerprint(const std::string& text);

/// The git revision this binary was built from ("<sha>", "<sha>-dirty" or "unknown").
std::string buildRevision();

}  // namespace superdyna::sweep

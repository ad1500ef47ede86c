#pragma once
// A sweep specification (YAML): which sequences, which system configurations, how many runs, and
// which tables to print. `superdyna sweep SPEC.yaml --out DIR` runs the matrix sequences x
// configs x runs and scores every cell with the same evaluation code as `superdyna eval`.
//
//   name: backbone
//   runs: 1
//   eval: {max_diff: 0.01, rpe_delta: 1.0, rpe_unit: m}
//   sequences:
//     - name: mh03                                  # simulated into DIR/sequences/mh03
//       simulate: [--scene, indoor, --duration, 60, --seed, 3]
//     - name: v101
//       dataset: euroc                              # any --dataset of `superdyna run`
//       path: ${SUPERDYNA_SHARED_DIR:-../../shared}/data/euroc/V1_01_easy
//       ground_truth: mav0/state_groundtruth_estimate0/data.csv   # relative to path
//   configs:
//     - name: orb-si
//       mode: stereo-inertial
//       config: ../configs/euroc_stereo_inertial.yaml   # relative to the spec file
//       set: {dynamic.mode: semantic}                   # dotted keys written into the config
//       args: [--loop-closing, off]                      # further `run` arguments
//       deterministic: true
//       runs: 1                                         # this config's runs (default: runs)
//       sequences: [mh03]                               # only these (default: all)
//     - name: peer                                      # an external system
//       command: "my_slam {path} {out}/traj.txt"        # run by /bin/sh in the cell folder
//       trajectory: "{out}/traj.txt"
//       trajectory_format: tum
//       time_unit: ns
//   tables:
//     - {name: ate, metric: ate_median, rows: sequences}
//
// Strings may use ${VAR} and ${VAR:-default} (environment). Relative paths are the spec file's
// folder's: in `path` and `config`, and in simulator and `run` arguments (both start there);
// an external command starts in its cell's folder ({out}). Errors name the file, line and field.

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace superdyna::sweep {

struct SequenceSpec {
  std::string name;
  /// `superdyna simulate` arguments (without --out); empty for a recorded dataset.
  std::vector<std::string> simulate_args;
  std::string dataset = "euroc";  ///< `run --dataset`.
  std::filesystem::path path;     ///< The dataset (absolute); empty when simulated.
  /// Further `run` arguments every config gets on this sequence (e.g. --calibration).
  std::vector<std::string> run_args;
  /// Relative to the dataset folder; empty = EuRoC's state_groundtruth_estimate0/data.csv.
  std::filesystem::path ground_truth;
  std::string ground_truth_format = "auto";
  std::filesystem::path ground_truth_times;  ///< KITTI times file (relative to the dataset).
  bool simulated() const { return !simulate_args.empty(); }
};

struct ConfigSpec {
  std::string name;
  std::string mode = "stereo";
  std::filesystem::path config;            ///< YAML options (absolute); empty = defaults.
  std::map<std::string, std::string> set;  ///< Dotted option keys -> YAML scalar values.
  std::vector<std::string> args;           ///< Further `run` arguments.
  bool deterministic = true;
  int runs = 0;                        ///< Runs of this config's cells; 0 = the spec's `runs`.
  std::string align;                   ///< "se3" / "sim3"; empty = by mode.
  std::vector<std::string> sequences;  ///< Only these sequences; empty = all.
  /// An external system: a shell command template. Placeholders: {path} {dataset} {mode}
  /// {sequence} {run} {out} (the cell folder) {gt}.
  std::string command;
  std::string trajectory = "{out}/trajectory.txt";  ///< Where the estimate lands (template).
  std::string trajectory_format = "auto";
  std::string time_unit = "s";  ///< TUM files only: "s" or "ns".
  bool external() const { return !command.empty(); }
  bool runsOn(const std::string& sequence) const;
  /// "sim3" for visual-only mono, else "se3", unless `align` is given.
  std::string alignment() const;
};

/// A table of the report: one metric, rows = sequences (columns = configs) or the transpose.
struct TableSpec {
  std::string name;
  std::string title;
  std::string metric = "ate_median";  ///< See tables.h, kMetrics.
  bool rows_are_configs = false;
  std::vector<std::string> configs;    ///< Subset and order; empty = all.
  std::vector<std::string> sequences;  ///< Subset and order; empty = all.
};

struct EvalSpec {
  double max_diff_s = 0.01;
  double rpe_delta = 1.0;
  std::string rpe_unit = "m";
};

struct SweepSpec {
  std::filesystem::path file;  ///< The spec file (absolute).
  std::string name;
  int runs = 1;
  EvalSpec eval;
  std::vector<SequenceSpec> sequences;
  std::vector<ConfigSpec> configs;
  std::vector<TableSpec> tables;
  const SequenceSpec& sequence(const std::string& name) const;
  const ConfigSpec& config(const std::string& name) const;
};

/// Reads and checks a spec: unique names, known modes / formats / metrics, existing config
/// files and datasets. Throws InputError naming the file, line and field.
SweepSpec loadSweepSpec(const std::filesystem::path& file);

/// ${VAR} and ${VAR:-default} replaced from the environment; an unset ${VAR} without default
/// throws InputError at `where`.
std::string expandEnvironment(const std::string& text, const std::string& where);

}  // namespace superdyna::sweep

#pragma once
// Where a sweep's tasks run: here (a pool of `jobs` workers), through GNU parallel (local jobs,
// or several machines with --sshlogin: they must see DIR and the binary at the same paths), or
// as a Slurm job array (an sbatch script written to DIR/dispatch and submitted with --wait).
// Remote workers run `superdyna sweep SPEC --out DIR --task KIND:INDEX`, one task each.

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace superdyna::sweep {

enum class DispatchKind { kLocal, kParallel, kSlurm };

/// "local", "parallel", "slurm"; OptionError naming --dispatch otherwise.
DispatchKind parseDispatchKind(const std::string& name);

struct DispatchOptions {
  DispatchKind kind = DispatchKind::kLocal;
  int jobs = 1;                          ///< Local workers; GNU parallel's --jobs.
  std::vector<std::string> ssh_logins;   ///< GNU parallel --sshlogin entries.
  std::vector<std::string> sbatch_args;  ///< Extra sbatch arguments (partition, time, cpus).
  std::filesystem::path superdyna;       ///< The binary the workers run.
  std::filesystem::path spec;
  std::filesystem::path out;
  bool rerun_failed = false;  ///< Passed on to the workers (--rerun-failed).
};

/// Runs every task of `tasks` ("cell:3") and returns when all have ended. `run_here` runs one
/// task in this process (local dispatch; exceptions are its own to report). `phase` names the
/// files written under DIR/dispatch ("sequences", "cells").
void dispatchTasks(const std::vector<std::string>& tasks, const std::string& phase,
                   const DispatchOptions& options,
                   const std::function<void(const std::string&)>& run_here);

/// The sbatch script of a phase: an array task maps SLURM_ARRAY_TASK_ID to the line of the
/// phase's task list and runs that task.
std::string slurmScript(const DispatchOptions& options, const std::filesystem::path& task_list,
                        const std::string& phase);

}  // namespace superdyna::sweep

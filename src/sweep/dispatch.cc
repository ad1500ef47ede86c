#include "superdyna/sweep/dispatch.h"

#include <fmt/format.h>

#include <atomic>
#include <thread>

#include "superdyna/core/atomic_file.h"
#include "superdyna/core/error.h"
#include "superdyna/sweep/process.h"

namespace superdyna::sweep {

namespace fs = std::filesystem;

namespace {

void runLocally(const std::vector<std::string>& tasks, int jobs,
                const std::function<void(const std::string&)>& run_here) {
  std::atomic<std::size_t> next{0};
  const auto worker = [&] {
    for (std::size_t i = next++; i < tasks.size(); i = next++)
      run_here(tasks[i]);
  };
  std::vector<std::thread> pool;
  const std::size_t workers = std::min<std::size_t>(std::max(jobs, 1), tasks.size());
  for (std::size_t i = 1; i < workers; ++i)
    pool.emplace_back(worker);
  worker();
  for (std::thread& t : pool)
    t.join();
}

fs::path writeTaskList(const std::vector<std::string>& tasks, const fs::path& dir,
                       const std::string& phase) {
  fs::create_directories(dir);
  const fs::path file = dir / (phase + ".tasks");
  AtomicFile out(file);
  for (const std::string& t : tasks)
    out.stream() << t << '\n';
  out.commit();
  return file;
}

std::vector<std::string> workerCommand(const DispatchOptions& o) {
  std::vector<std::string> command = {o.superdyna.string(), "sweep", o.spec.string(), "--out",
                                      o.out.string()};
  if (o.rerun_failed) command.push_back("--rerun-failed");
  command.push_back("--task");
  return command;
}

void runWithParallel(const DispatchOptions& o, const fs::path& task_list,
                     const std::string& phase) {
  const fs::path dir = task_list.parent_path();
  std::vector<std::string> command = {"parallel",     "--will-cite",
                                      "--jobs",       std::to_string(o.jobs),
                                      "--joblog",     (dir / (phase + ".joblog")).string(),
                                      "--line-buffer"};
  for (const std::string& login : o.ssh_logins)
    command.insert(command.end(), {"--sshlogin", login});
  const std::vector<std::string> worker = workerCommand(o);
  command.insert(command.end(), worker.begin(), worker.end());
  command.insert(command.end(), {"{}", "::::", task_list.string()});
  fmt::print("dispatch: {}\n", shellQuote(command));
  std::fflush(stdout);
  const fs::path log = dir / (phase + ".parallel.log");
  const ProcessResult p = runProcess(command, log, dir);
  if (p.exit_code == 255 || p.exit_code == 127 || p.signal != 0) {
    throw InputError(InputLocation(log), fmt::format("GNU parallel failed ({}):\n{}", p.describe(),
                                                     tailOfFile(log, 10)));
  }
}

void runWithSlurm(const DispatchOptions& o, const fs::path& task_list, const std::string& phase,
                  std::size_t count) {
  const fs::path dir = task_list.parent_path();
  const fs::path script = dir / (phase + ".sbatch");
  {
    AtomicFile out(script);
    out.stream() << slurmScript(o, task_list, phase);
    out.commit();
  }
  std::vector<std::string> command = {"sbatch", "--wait", fmt::format("--array=0-{}", count - 1)};
  command.insert(command.end(), o.sbatch_args.begin(), o.sbatch_args.end());
  command.push_back(script.string());
  fmt::print("dispatch: {}\n", shellQuote(command));
  std::fflush(stdout);
  const fs::path log = dir / (phase + ".sbatch.log");
  const ProcessResult p = runProcess(command, log, dir);
  // sbatch --wait exits with the array's highest exit code: a failed task is reported by the
  // sweep from its cell; only a failed submission stops here.
  const std::string said = tailOfFile(log, 10);
  if (said.find("Submitted batch job") == std::string::npos) {
    throw InputError(InputLocation(log), fmt::format("sbatch did not submit the {} ({}):\n{}",
                                                     phase, p.describe(), said));
  }
}

}  // namespace

DispatchKind parseDispatchKind(const std::string& name) {
  if (name == "local") return DispatchKind::kLocal;
  if (name == "parallel") return DispatchKind::kParallel;
  if (name == "slurm") return DispatchKind::kSlurm;
  throw OptionError("--dispatch", fmt::format("'{}' is not local, parallel or slurm", name));
}

std::string slurmScript(const DispatchOptions& o, const fs::path& task_list,
                        const std::string& phase) {
  const fs::path dir = task_list.parent_path();
  return fmt::format(
      "#!/bin/bash\n"
      "# superdyna sweep: the {phase} of {spec} as a Slurm job array (one task per array index).\n"
      "#SBATCH --job-name=superdyna-{phase}\n"
      "#SBATCH --output={dir}/{phase}-%a.log\n"
      "#SBATCH --ntasks=1\n"
      "set -euo pipefail\n"
      "task=$(sed -n \"$((SLURM_ARRAY_TASK_ID + 1))p\" {list})\n"
      "exec {worker} \"$task\"\n",
      fmt::arg("phase", phase), fmt::arg("spec", o.spec.string()), fmt::arg("dir", dir.string()),
      fmt::arg("list", shellQuote({task_list.string()})),
      fmt::arg("worker", shellQuote(workerCommand(o))));
}

void dispatchTasks(const std::vector<std::string>& tasks, const std::string& phase,
                   const DispatchOptions& options,
                   const std::function<void(const std::string&)>& run_here) {
  if (tasks.empty()) return;
  if (options.kind == DispatchKind::kLocal) {
    runLocally(tasks, options.jobs, run_here);
    return;
  }
  const fs::path list = writeTaskList(tasks, options.out / "dispatch", phase);
  if (options.kind == DispatchKind::kParallel) {
    runWithParallel(options, list, phase);
  } else {
    runWithSlurm(options, list, phase, tasks.size());
  }
}

}  // namespace superdyna::sweep

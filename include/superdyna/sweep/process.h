#pragma once
// Runs one command of a sweep as a child process, its output in a log file, and measures it as
// the kernel accounts it (wait4): wall time, user + system CPU time of the process and every
// child it waited for, and the peak resident memory. The child dies with the sweep (Linux
// PR_SET_PDEATHSIG), so a killed sweep leaves no orphaned run writing into its cells.

#include <filesystem>
#include <string>
#include <vector>

namespace superdyna::sweep {

struct ProcessResult {
  int exit_code = -1;  ///< The exit status, or -1 when a signal ended the process.
  int signal = 0;      ///< The signal that ended it, else 0.
  double wall_s = 0.0;
  double cpu_s = 0.0;
  double peak_rss_mb = 0.0;
  bool ok() const { return exit_code == 0; }
  /// "exit status 2" / "killed by signal 9 (Killed)".
  std::string describe() const;
};

/// Runs argv[0] (looked up in PATH when it has no '/') with `argv` in `cwd`, stdout and stderr
/// appended to `log`. Throws InputError when the log cannot be opened or the process not started.
ProcessResult runProcess(const std::vector<std::string>& argv, const std::filesystem::path& log,
                         const std::filesystem::path& cwd);

/// The command line as a shell would need it typed (each argument quoted where needed).
std::string shellQuote(const std::vector<std::string>& argv);

/// The last `lines` lines of a text file (for error messages); empty when unreadable.
std::string tailOfFile(const std::filesystem::path& file, int lines);

}  // namespace superdyna::sweep

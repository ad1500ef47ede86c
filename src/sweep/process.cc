#include "superdyna/sweep/process.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <deque>
#include <fstream>

#include "superdyna/core/error.h"

namespace superdyna::sweep {

namespace fs = std::filesystem;

namespace {

double seconds(const timeval& tv) {
  return static_cast<double>(tv.tv_sec) + 1e-6 * static_cast<double>(tv.tv_usec);
}

/// In the child between fork and exec: only async-signal-safe calls.
[[noreturn]] void execChild(const std::vector<char*>& args, int log_fd, const char* cwd,
                            pid_t parent) {
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (getppid() != parent) _exit(127);  // the sweep died before prctl took effect
  dup2(log_fd, STDOUT_FILENO);
  dup2(log_fd, STDERR_FILENO);
  close(log_fd);
  if (chdir(cwd) != 0) _exit(126);
  execvp(args[0], args.data());
  const char message[] = "superdyna sweep: cannot execute the command\n";
  (void)!write(STDERR_FILENO, message, sizeof(message) - 1);
  _exit(127);
}

}  // namespace

std::string ProcessResult::describe() const {
  if (signal != 0) return fmt::format("killed by signal {} ({})", signal, strsignal(signal));
  return fmt::format("exit status {}", exit_code);
}

ProcessResult runProcess(const std::vector<std::string>& argv, const fs::path& log,
                         const fs::path& cwd) {
  if (argv.empty()) throw InputError("runProcess: empty command");
  const int log_fd = open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (log_fd < 0)
    throw InputError(InputLocation(log), fmt::format("cannot open: {}", strerror(errno)));
  std::vector<std::string> copies = argv;
  std::vector<char*> args;
  for (std::string& a : copies)
    args.push_back(a.data());
  args.push_back(nullptr);
  const std::string dir = cwd.string();
  const pid_t parent = getpid();
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid < 0) {
    close(log_fd);
    throw InputError(fmt::format("cannot start '{}': {}", argv[0], strerror(errno)));
  }
  if (pid == 0) execChild(args, log_fd, dir.c_str(), parent);
  close(log_fd);
  int status = 0;
  rusage usage{};
  while (wait4(pid, &status, 0, &usage) < 0) {
    if (errno != EINTR)
      throw InputError(fmt::format("waiting for '{}': {}", argv[0], strerror(errno)));
  }
  ProcessResult result;
  result.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.cpu_s = seconds(usage.ru_utime) + seconds(usage.ru_stime);
  result.peak_rss_mb = static_cast<double>(usage.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB
  if (WIFEXITED(status)) result.exit_code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) result.signal = WTERMSIG(status);
  return result;
}

std::string shellQuote(const std::vector<std::string>& argv) {
  std::string line;
  for (const std::string& a : argv) {
    if (!line.empty()) line += ' ';
    const bool plain = !a.empty() && a.find_first_not_of(
                                         "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOP"
                                         "QRSTUVWXYZ0123456789-_./=:,+@%") == std::string::npos;
    if (plain) {
      line += a;
      continue;
    }
    line += '\'';
    for (char ch : a)
      line += ch == '\'' ? std::string("'\\''") : std::string(1, ch);
    line += '\'';
  }
  return line;
}

std::string tailOfFile(const fs::path& file, int lines) {
  std::ifstream in(file);
  std::deque<std::string> last;
  std::string line;
  while (std::getline(in, line)) {
    last.push_back(line);
    if (static_cast<int>(last.size()) > lines) last.pop_front();
  }
  std::string out;
  for (const std::string& l : last)
    out += l + '\n';
  return out;
}

}  // namespace superdyna::sweep

#pragma once
// A helper thread that runs one job at a time for its owner: run() hands it a job and returns at
// once, wait() blocks until the job is done and rethrows what the job threw. The owner works in
// between (the front end extracts the left image while the helper extracts the right one). The
// thread starts with the first job and lives until the TaskThread is destroyed, so the per-thread
// state of libraries used by the jobs (e.g. ONNX Runtime's scratch buffers) is set up once.
//
// Single owner: run(), wait() and the destructor must not be called concurrently (one thread, or
// threads that take turns, such as the mapping thread and the tracker while the mapping thread is
// idle).

#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>

namespace superdyna {

/// CPU time the calling thread has used so far [ms] (unlike wall-clock time, not inflated when
/// other processes compete for the cores).
double threadCpuMs();

class TaskThread {
 public:
  TaskThread() = default;
  /// Waits for a job still running (its error is dropped), then ends the thread.
  ~TaskThread();
  TaskThread(const TaskThread&) = delete;
  TaskThread& operator=(const TaskThread&) = delete;

  /// Starts `job` on the helper thread. Throws std::logic_error while an earlier job has not
  /// been waited for.
  void run(std::function<void()> job);
  /// Blocks until the job given to run() has finished and rethrows its exception, if any. Returns
  /// at once when no job is outstanding.
  void wait();
  /// A job was given to run() and not yet waited for.
  bool outstanding() const;
  /// The outstanding job has finished: wait() would return at once.
  bool finished() const;
  /// CPU time the helper thread has spent in jobs so far [ms].
  double cpuMs() const;

 private:
  void loop();

  std::thread thread_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::function<void()> job_;  ///< Given to run(), not yet started.
  bool outstanding_ = false;   ///< A job was given and not yet waited for.
  bool finished_ = false;      ///< The outstanding job has finished.
  bool stopping_ = false;
  std::exception_ptr error_;
  double cpu_ms_ = 0.0;
};

}  // namespace superdyna

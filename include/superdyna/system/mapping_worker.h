#pragma once
// The local-mapping thread of the concurrent System: a MappingSink that runs the tracker's mapping
// jobs (keyframe registration, local BA, resets) one at a time, in order, in its own thread, fed by
// a bounded queue. Tracking only waits when the queue is full (or at a map reset), never for a
// local BA to end. The loop closer's thread (LoopStage) is one too.
//
// Errors: an exception of a job stops the thread; the error is rethrown to the tracking thread by
// the next submit(), discardPending() or finish() (the jobs queued after it are dropped), so a
// failed mapping step ends the run instead of hanging or terminating it.

#include <condition_variable>
#include <cstddef>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>

#include "superdyna/core/bounded_queue.h"
#include "superdyna/core/task_thread.h"
#include "superdyna/tracking/tracker.h"

namespace superdyna::system {

using superdyna::threadCpuMs;  // core/task_thread.h

class MappingWorker final : public tracking::MappingSink {
 public:
  /// capacity = jobs that may wait, >= 1. The thread starts with the first job.
  explicit MappingWorker(std::size_t capacity);
  /// Drops the queued jobs and joins the thread; errors are not rethrown here.
  ~MappingWorker() override;
  MappingWorker(const MappingWorker&) = delete;
  MappingWorker& operator=(const MappingWorker&) = delete;

  /// Queues the job, waiting while the queue is full.
  void submit(std::function<void()> job) override;
  void discardPending() override;
  void waitIdle() override;
  bool busy() const override;
  /// Jobs submitted and neither finished nor discarded yet (queued or running).
  std::size_t unfinished() const;
  /// Runs every queued job, then joins the thread. A later submit() starts a new thread.
  void finish();

  /// Wall-clock time spent running jobs so far [ms].
  double busyMs() const;
  /// CPU time of the worker's threads so far [ms], up to the end of the last job.
  double cpuMs() const;
  /// Jobs run so far.
  std::size_t jobsRun() const;

 private:
  void start();
  void loop(BoundedQueue<std::function<void()>>& queue);
  void rethrowError() const;

  std::size_t capacity_;
  std::unique_ptr<BoundedQueue<std::function<void()>>> queue_;
  std::thread thread_;
  mutable std::mutex mutex_;
  std::condition_variable idle_;
  std::size_t unfinished_ = 0;  ///< Submitted and neither run nor discarded yet.
  std::exception_ptr error_;    ///< First error of a job; sticky.
  double busy_ms_ = 0.0;
  double cpu_ms_ = 0.0;
  std::size_t jobs_run_ = 0;
};

}  // namespace superdyna::system

#include "superdyna/core/task_thread.h"

#include <ctime>
#include <stdexcept>
#include <utility>

namespace superdyna {

double threadCpuMs() {
  timespec now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return 1e3 * static_cast<double>(now.tv_sec) + 1e-6 * static_cast<double>(now.tv_nsec);
}

TaskThread::~TaskThread() {
  if (!thread_.joinable()) return;
  {
    const std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

void TaskThread::run(std::function<void()> job) {
  {
    const std::lock_guard lock(mutex_);
    if (outstanding_)
      throw std::logic_error("TaskThread::run: the previous job was not waited for");
    job_ = std::move(job);
    outstanding_ = true;
    finished_ = false;
    error_ = nullptr;
  }
  if (!thread_.joinable()) thread_ = std::thread([this] { loop(); });
  changed_.notify_all();
}

void TaskThread::wait() {
  std::unique_lock lock(mutex_);
  if (!outstanding_) return;
  changed_.wait(lock, [&] { return finished_; });
  outstanding_ = false;
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

bool TaskThread::outstanding() const {
  const std::lock_guard lock(mutex_);
  return outstanding_;
}

bool TaskThread::finished() const {
  const std::lock_guard lock(mutex_);
  return outstanding_ && finished_;
}

double TaskThread::cpuMs() const {
  const std::lock_guard lock(mutex_);
  return cpu_ms_;
}

void TaskThread::loop() {
  std::unique_lock lock(mutex_);
  while (true) {
    changed_.wait(lock, [&] { return job_ != nullptr || stopping_; });
    if (job_ == nullptr) return;  // stopping with nothing left to do
    std::function<void()> job = std::exchange(job_, nullptr);
    lock.unlock();
    std::exception_ptr error;
    const double cpu_start = threadCpuMs();
    try {
      job();
    } catch (...) {
      error = std::current_exception();
    }
    const double cpu_ms = threadCpuMs() - cpu_start;
    lock.lock();
    cpu_ms_ += cpu_ms;
    error_ = error;
    finished_ = true;
    changed_.notify_all();
  }
}

}  // namespace superdyna

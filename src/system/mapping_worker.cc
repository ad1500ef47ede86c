#include "superdyna/system/mapping_worker.h"

#include <chrono>
#include <stdexcept>
#include <utility>

#include "superdyna/core/time.h"

namespace superdyna::system {

namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

MappingWorker::MappingWorker(std::size_t capacity) : capacity_(capacity) {
  if (capacity_ == 0) throw std::invalid_argument("MappingWorker: capacity must be >= 1");
}

MappingWorker::~MappingWorker() {
  if (!thread_.joinable()) return;
  queue_->clear();
  queue_->close();
  thread_.join();
}

void MappingWorker::start() {
  queue_ = std::make_unique<BoundedQueue<std::function<void()>>>(capacity_);
  thread_ = std::thread([this, queue = queue_.get()] { loop(*queue); });
}

void MappingWorker::submit(std::function<void()> job) {
  rethrowError();
  if (!thread_.joinable()) start();
  {
    const std::lock_guard lock(mutex_);
    ++unfinished_;
  }
  if (queue_->push(std::move(job))) return;
  {
    const std::lock_guard lock(mutex_);
    --unfinished_;
  }
  rethrowError();  // the queue only closes early after an error
  throw std::logic_error("MappingWorker: submit to a stopped worker");
}

void MappingWorker::discardPending() {
  if (thread_.joinable()) {
    const std::size_t dropped = queue_->clear();
    std::unique_lock lock(mutex_);
    unfinished_ -= dropped;
    idle_.wait(lock, [&] { return unfinished_ == 0; });
  }
  rethrowError();
}

void MappingWorker::waitIdle() {
  if (thread_.joinable()) {
    std::unique_lock lock(mutex_);
    idle_.wait(lock, [&] { return unfinished_ == 0 || error_ != nullptr; });
  }
  rethrowError();
}

bool MappingWorker::busy() const {
  const std::lock_guard lock(mutex_);
  return unfinished_ > 0;
}

std::size_t MappingWorker::unfinished() const {
  const std::lock_guard lock(mutex_);
  return unfinished_;
}

void MappingWorker::finish() {
  if (thread_.joinable()) {
    queue_->close();
    thread_.join();
    queue_.reset();
  }
  rethrowError();
}

void MappingWorker::loop(BoundedQueue<std::function<void()>>& queue) {
  double cpu_start = threadCpuMs();
  while (std::optional<std::function<void()>> job = queue.pop()) {
    const auto start = Clock::now();
    std::exception_ptr error;
    try {
      (*job)();
    } catch (...) {
      error = std::current_exception();
    }
    const std::lock_guard lock(mutex_);
    busy_ms_ += millisecondsSince(start);
    const double cpu_now = threadCpuMs();
    cpu_ms_ += cpu_now - cpu_start;
    cpu_start = cpu_now;
    ++jobs_run_;
    --unfinished_;
    if (error) {
      error_ = error;
      queue.close();  // refuse further jobs; the queued ones are dropped
      unfinished_ -= queue.clear();
    }
    idle_.notify_all();
    if (error) return;
  }
}

void MappingWorker::rethrowError() const {
  std::exception_ptr error;
  {
    const std::lock_guard lock(mutex_);
    error = error_;
  }
  if (error) std::rethrow_exception(error);
}

double MappingWorker::busyMs() const {
  const std::lock_guard lock(mutex_);
  return busy_ms_;
}

double MappingWorker::cpuMs() const {
  const std::lock_guard lock(mutex_);
  return cpu_ms_;
}

std::size_t MappingWorker::jobsRun() const {
  const std::lock_guard lock(mutex_);
  return jobs_run_;
}

}  // namespace superdyna::system

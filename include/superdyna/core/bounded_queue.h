#pragma once
// A bounded multi-producer / multi-consumer FIFO queue for handing work between threads.
//
// push() blocks while the queue is full, pop() while it is empty, so a fast producer cannot run
// arbitrarily far ahead of a slow consumer. close() ends the hand-off: it wakes every waiting
// thread, later pushes are refused (push returns false) and pop() still returns the items already
// queued, then nullopt once the queue is empty. That lets a producer signal "no more items" and a
// consumer drain what is left, and lets either side stop the other (e.g. after an error) without
// a thread staying blocked.

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <utility>

namespace superdyna {

template <typename T>
class BoundedQueue {
 public:
  /// capacity >= 1 items; throws std::invalid_argument otherwise.
  explicit BoundedQueue(std::size_t capacity) : capacity_(capacity) {
    if (capacity_ == 0) throw std::invalid_argument("BoundedQueue: capacity must be >= 1");
  }
  BoundedQueue(const BoundedQueue&) = delete;
  BoundedQueue& operator=(const BoundedQueue&) = delete;

  /// Appends the item, waiting while the queue is full. Returns false (and drops the item) when the
  /// queue is or becomes closed before there is room.
  bool push(T item) {
    std::unique_lock lock(mutex_);
    not_full_.wait(lock, [&] { return closed_ || items_.size() < capacity_; });
    if (closed_) return false;
    items_.push_back(std::move(item));
    lock.unlock();
    not_empty_.notify_one();
    return true;
  }

  /// The oldest item, waiting while the queue is empty and open; nullopt once it is closed and
  /// empty.
  std::optional<T> pop() {
    std::unique_lock lock(mutex_);
    not_empty_.wait(lock, [&] { return closed_ || !items_.empty(); });
    if (items_.empty()) return std::nullopt;
    T item = std::move(items_.front());
    items_.pop_front();
    lock.unlock();
    not_full_.notify_one();
    return item;
  }

  /// Refuses further pushes and wakes every waiting thread. Idempotent.
  void close() {
    {
      const std::lock_guard lock(mutex_);
      closed_ = true;
    }
    not_full_.notify_all();
    not_empty_.notify_all();
  }

  /// Removes every queued item (waking blocked producers); returns how many were removed.
  std::size_t clear() {
    std::size_t removed = 0;
    {
      const std::lock_guard lock(mutex_);
      removed = items_.size();
      items_.clear();
    }
    not_full_.notify_all();
    return removed;
  }

  std::size_t size() const {
    const std::lock_guard lock(mutex_);
    return items_.size();
  }
  bool closed() const {
    const std::lock_guard lock(mutex_);
    return closed_;
  }
  std::size_t capacity() const { return capacity_; }

 private:
  const std::size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable not_full_, not_empty_;
  std::deque<T> items_;
  bool closed_ = false;
};

}  // namespace superdyna

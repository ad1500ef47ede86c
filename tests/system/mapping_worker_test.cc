#include "superdyna/system/mapping_worker.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

#include "support/test_support.h"

namespace superdyna::system {
namespace {

/// A job that blocks until release() (to hold the worker busy while the test queues more).
class Gate {
 public:
  void waitOpen() {
    entered_ = true;
    while (!open_)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  void waitEntered() const {
    while (!entered_)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  void release() { open_ = true; }

 private:
  std::atomic<bool> entered_{false}, open_{false};
};

TEST(MappingWorker, RunsJobsInOrderInOneOtherThread) {
  MappingWorker worker(2);
  std::mutex mutex;
  std::vector<int> order;
  std::vector<std::thread::id> threads;
  for (int i = 0; i < 50; ++i) {
    worker.submit([&, i] {
      const std::lock_guard lock(mutex);
      order.push_back(i);
      threads.push_back(std::this_thread::get_id());
    });
  }
  worker.finish();
  ASSERT_EQ(order.size(), 50u);
  for (int i = 0; i < 50; ++i)
    EXPECT_EQ(order[static_cast<std::size_t>(i)], i);
  for (const std::thread::id id : threads) {
    EXPECT_EQ(id, threads.front());
    EXPECT_NE(id, std::this_thread::get_id());
  }
  EXPECT_EQ(worker.jobsRun(), 50u);
  EXPECT_GE(worker.busyMs(), 0.0);
}

TEST(MappingWorker, AcceptsJobsAgainAfterFinish) {
  MappingWorker worker(1);
  int runs = 0;  // finish() joins the thread, so reading after it is safe
  worker.submit([&] { ++runs; });
  worker.finish();
  EXPECT_EQ(runs, 1);
  worker.submit([&] { ++runs; });
  worker.finish();
  worker.finish();  // idempotent
  EXPECT_EQ(runs, 2);
}

TEST(MappingWorker, DiscardPendingDropsQueuedJobsAndWaitsForTheRunningOne) {
  MappingWorker worker(4);
  Gate gate;
  std::atomic<bool> first_done{false};
  std::atomic<int> later_runs{0};
  worker.submit([&] {
    gate.waitOpen();
    first_done = true;
  });
  gate.waitEntered();
  for (int i = 0; i < 3; ++i)
    worker.submit([&] { ++later_runs; });
  std::thread releaser([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    gate.release();
  });
  worker.discardPending();
  EXPECT_TRUE(first_done.load());  // returned only after the running job ended
  releaser.join();
  worker.submit([&] { later_runs += 10; });
  worker.finish();
  EXPECT_EQ(later_runs.load(), 10);  // the three queued jobs were dropped
}

TEST(MappingWorker, IsBusyFromSubmitUntilTheLastJobEnds) {
  MappingWorker worker(4);
  EXPECT_FALSE(worker.busy());
  Gate gate;
  worker.submit([&] { gate.waitOpen(); });
  worker.submit([] {});
  EXPECT_TRUE(worker.busy());
  gate.waitEntered();
  EXPECT_TRUE(worker.busy());  // the first job runs, the second waits
  gate.release();
  worker.waitIdle();
  EXPECT_FALSE(worker.busy());
  worker.finish();
}

TEST(MappingWorker, AJobErrorReachesTheSubmitter) {
  MappingWorker worker(1);
  worker.submit([] { throw std::runtime_error("local BA failed"); });
  // The error surfaces at the latest in finish(); submits after it rethrow it as well.
  test::expectError<std::runtime_error>([&] { worker.finish(); }, {"local BA failed"});
  test::expectError<std::runtime_error>([&] { worker.submit([] {}); }, {"local BA failed"});
  test::expectError<std::runtime_error>([&] { worker.discardPending(); }, {"local BA failed"});
}

TEST(MappingWorker, ABlockedSubmitEndsWhenAJobFails) {
  MappingWorker worker(1);
  Gate gate;
  worker.submit([&] {
    gate.waitOpen();
    throw std::runtime_error("mapping error");
  });
  gate.waitEntered();
  worker.submit([] {});  // fills the queue
  std::thread releaser([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    gate.release();
  });
  // Waits for room; the failing job closes the queue, so this throws instead of hanging.
  test::expectError<std::runtime_error>([&] { worker.submit([] {}); }, {"mapping error"});
  releaser.join();
}

TEST(MappingWorker, DestructionDropsQueuedJobs) {
  std::atomic<int> runs{0};
  Gate gate;
  {
    MappingWorker worker(8);
    worker.submit([&] {
      gate.waitOpen();
      ++runs;
    });
    gate.waitEntered();
    for (int i = 0; i < 5; ++i)
      worker.submit([&] { ++runs; });
    gate.release();
  }
  EXPECT_GE(runs.load(), 1);
  EXPECT_LE(runs.load(), 6);
}

TEST(MappingWorker, RejectsZeroCapacity) {
  EXPECT_THROW(MappingWorker(0), std::invalid_argument);
}

}  // namespace
}  // namespace superdyna::system

#include "superdyna/core/task_thread.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>

namespace superdyna {
namespace {

TEST(TaskThread, RunsTheJobOnAnotherThreadWhileTheCallerWorks) {
  TaskThread helper;
  const std::thread::id caller = std::this_thread::get_id();
  std::thread::id ran_on;
  std::atomic<bool> caller_done{false};
  bool saw_caller_done = false;
  helper.run([&] {
    ran_on = std::this_thread::get_id();
    while (!caller_done.load())
      std::this_thread::yield();  // only ends if run() returned first
    saw_caller_done = true;
  });
  caller_done = true;
  helper.wait();
  EXPECT_NE(ran_on, caller);
  EXPECT_TRUE(saw_caller_done);
}

TEST(TaskThread, RunsJobsInTurnOnTheSameThread) {
  TaskThread helper;
  std::thread::id first, second;
  int sum = 0;
  helper.run([&] {
    first = std::this_thread::get_id();
    sum += 2;
  });
  helper.wait();
  helper.run([&] {
    second = std::this_thread::get_id();
    sum *= 10;
  });
  helper.wait();
  EXPECT_EQ(sum, 20);
  EXPECT_EQ(first, second);
}

TEST(TaskThread, WaitRethrowsTheJobsErrorOnce) {
  TaskThread helper;
  helper.run([] { throw std::runtime_error("right image failed"); });
  try {
    helper.wait();
    FAIL() << "wait() did not rethrow";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "right image failed");
  }
  EXPECT_NO_THROW(helper.wait());  // nothing outstanding any more
  int value = 0;
  helper.run([&] { value = 7; });  // the thread survives a failed job
  helper.wait();
  EXPECT_EQ(value, 7);
}

TEST(TaskThread, RefusesASecondJobBeforeTheFirstIsWaitedFor) {
  TaskThread helper;
  helper.run([] {});
  EXPECT_THROW(helper.run([] {}), std::logic_error);
  helper.wait();
  EXPECT_NO_THROW(helper.run([] {}));
  helper.wait();
}

TEST(TaskThread, TellsWhetherItsJobIsOutstandingAndFinishedWithoutWaiting) {
  TaskThread helper;
  EXPECT_FALSE(helper.outstanding());
  EXPECT_FALSE(helper.finished());
  std::atomic<bool> release{false};
  helper.run([&] {
    while (!release)
      std::this_thread::yield();
  });
  EXPECT_TRUE(helper.outstanding());
  EXPECT_FALSE(helper.finished());  // held until released
  release = true;
  while (!helper.finished())
    std::this_thread::yield();
  EXPECT_TRUE(helper.outstanding());  // finished, not yet waited for
  helper.wait();
  EXPECT_FALSE(helper.outstanding());
  EXPECT_FALSE(helper.finished());
}

TEST(TaskThread, CountsTheCpuTimeOfItsJobs) {
  TaskThread helper;
  EXPECT_EQ(helper.cpuMs(), 0.0);
  volatile double sink = 0.0;
  helper.run([&] {
    const double start = threadCpuMs();
    while (threadCpuMs() - start < 5.0)
      sink = sink + 1.0;  // busy for 5 ms of CPU
  });
  helper.wait();
  EXPECT_GE(helper.cpuMs(), 5.0);
  EXPECT_GT(sink, 0.0);
}

TEST(TaskThread, DestructionWaitsForARunningJob) {
  std::atomic<bool> finished{false};
  {
    TaskThread helper;
    helper.run([&] {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      finished = true;
    });
  }
  EXPECT_TRUE(finished.load());
}

}  // namespace
}  // namespace superdyna

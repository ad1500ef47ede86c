#include "superdyna/core/process_memory.h"

#include <gtest/gtest.h>

#include <cstring>
#include <memory>
#include <vector>

namespace superdyna {
namespace {

TEST(ProcessMemory, ResidentSetGrowsByWhatThisProcessTouches) {
  const std::optional<std::uint64_t> before = residentSetBytes();
  ASSERT_TRUE(before.has_value()) << "/proc/self/statm not readable";
  EXPECT_GT(*before, 1u << 20);  // a test binary with its libraries: over 1 MB resident

  constexpr std::size_t kBytes = 64u << 20;
  const auto block = std::make_unique<char[]>(kBytes);
  std::memset(block.get(), 1, kBytes);  // touch every page, so that it becomes resident
  const std::optional<std::uint64_t> after = residentSetBytes();
  ASSERT_TRUE(after.has_value());
  EXPECT_GE(*after, *before + kBytes * 9 / 10);
  EXPECT_EQ(block[kBytes - 1], 1);
}

TEST(ProcessMemory, HeapInUseCountsALiveAllocationAndNotAFreedOne) {
  const std::optional<HeapUsage> before = heapUsage();
  if (!before) GTEST_SKIP() << "malloc is not glibc's: no allocator statistics";
  constexpr std::size_t kBytes = 32u << 20;
  auto block = std::make_unique<char[]>(kBytes);
  block[0] = 1;
  const std::optional<HeapUsage> during = heapUsage();
  ASSERT_TRUE(during.has_value());
  EXPECT_GE(during->in_use_bytes, before->in_use_bytes + kBytes);
  block.reset();
  const std::optional<HeapUsage> after = heapUsage();
  ASSERT_TRUE(after.has_value());
  EXPECT_LE(after->in_use_bytes, during->in_use_bytes - kBytes);
}

TEST(ProcessMemory, ReleasingTheHeapReturnsPagesFreedBelowALiveBlock) {
  if (!heapUsage()) GTEST_SKIP() << "malloc is not glibc's: no allocator control";
  // 64 MB of small blocks (below the mmap threshold: they come from the heap), then one block
  // above them that stays alive: freeing the small ones leaves a free hole that glibc does not
  // return by itself, as culled keyframes leave under newer ones in a long run.
  constexpr std::size_t kBlock = 1024;
  constexpr std::size_t kCount = 64 * 1024;
  std::vector<std::unique_ptr<char[]>> blocks(kCount);
  for (auto& block : blocks) {
    block = std::make_unique<char[]>(kBlock);
    std::memset(block.get(), 1, kBlock);
  }
  const auto live = std::make_unique<char[]>(kBlock);
  live[0] = 1;
  blocks.clear();
  const std::optional<std::uint64_t> kept = residentSetBytes();
  ASSERT_TRUE(kept.has_value());
  EXPECT_TRUE(releaseFreeHeapMemory());
  const std::optional<std::uint64_t> released = residentSetBytes();
  ASSERT_TRUE(released.has_value());
  EXPECT_LE(*released + kBlock * kCount / 2, *kept);
  EXPECT_EQ(live[0], 1);
}

}  // namespace
}  // namespace superdyna

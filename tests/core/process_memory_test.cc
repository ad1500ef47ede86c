#include "superdyna/core/process_memory.h"

#include <gtest/gtest.h>

#include <cstring>
#include <memory>

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

}  // namespace
}  // namespace superdyna

#include "superdyna/core/process_memory.h"

#include <unistd.h>

#include <fstream>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

// Sanitizers replace malloc with their own allocator: glibc's statistics and trimming then see
// an allocator that holds nothing.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define SUPERDYNA_SANITIZED_MALLOC
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
#define SUPERDYNA_SANITIZED_MALLOC
#endif
#endif
#if defined(__GLIBC__) && !defined(SUPERDYNA_SANITIZED_MALLOC) && \
    (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 33))
#define SUPERDYNA_GLIBC_MALLOC 1
#else
#define SUPERDYNA_GLIBC_MALLOC 0
#endif

namespace superdyna {

std::optional<std::uint64_t> residentSetBytes() {
  std::ifstream statm("/proc/self/statm");
  std::uint64_t total_pages = 0;
  std::uint64_t resident_pages = 0;
  if (!(statm >> total_pages >> resident_pages)) return std::nullopt;
  const long page_size = sysconf(_SC_PAGESIZE);
  if (page_size <= 0) return std::nullopt;
  return resident_pages * static_cast<std::uint64_t>(page_size);
}

std::optional<HeapUsage> heapUsage() {
#if SUPERDYNA_GLIBC_MALLOC
  const struct mallinfo2 info = mallinfo2();
  return HeapUsage{info.uordblks + info.hblkhd, info.fordblks};
#else
  return std::nullopt;
#endif
}

bool releaseFreeHeapMemory() {
#if SUPERDYNA_GLIBC_MALLOC
  return malloc_trim(0) == 1;
#else
  return false;
#endif
}

}  // namespace superdyna

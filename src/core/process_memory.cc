#include "superdyna/core/process_memory.h"

#include <unistd.h>

#include <fstream>

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

}  // namespace superdyna

#pragma once
// The process's resident memory, for progress lines and the memory benchmark (Linux /proc).

#include <cstdint>
#include <optional>

namespace superdyna {

/// Resident set size of this process [bytes] (/proc/self/statm's second field times the page
/// size); nullopt where /proc is not available.
std::optional<std::uint64_t> residentSetBytes();

/// What the C allocator holds, to tell growing data from a fragmented heap (glibc's mallinfo2).
struct HeapUsage {
  std::uint64_t in_use_bytes = 0;  ///< allocated and not freed (small chunks and mmap'd blocks)
  std::uint64_t free_bytes = 0;    ///< freed but kept by the allocator inside its arenas
};

/// The allocator's counts over all arenas; nullopt where malloc is not glibc's (another C
/// library, or a sanitizer's allocator).
std::optional<HeapUsage> heapUsage();

/// Hands the allocator's free pages back to the system (glibc's malloc_trim(0)). glibc returns
/// only the top of a heap by itself; pages freed below a live block stay resident, so a long run
/// that frees and reallocates (culled keyframes, rebuilt indices, several threads' arenas) grows
/// its RSS with no data behind it. Takes a few milliseconds and holds each arena's lock meanwhile:
/// call it now and then (`superdyna run` does every 10 s), not per frame. False where malloc is
/// not glibc's or nothing was released.
bool releaseFreeHeapMemory();

}  // namespace superdyna

#pragma once
// The process's resident memory, for progress lines and the memory benchmark (Linux /proc).

#include <cstdint>
#include <optional>

namespace superdyna {

/// Resident set size of this process [bytes] (/proc/self/statm's second field times the page
/// size); nullopt where /proc is not available.
std::optional<std::uint64_t> residentSetBytes();

}  // namespace superdyna

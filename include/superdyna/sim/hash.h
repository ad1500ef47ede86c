#pragma once
// Counter-based pseudo-random numbers for the simulator: a value is a pure function of its
// inputs (seed, time, pixel, ...), so results do not depend on threads or call order.

#include <cstdint>

namespace superdyna::sim {

/// SplitMix64 finaliser: decorrelates nearby inputs (1 and 2 give unrelated outputs).
inline std::uint64_t mix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

/// A number in [0, 1) from the top 53 bits of a hash.
inline double unitFromHash(std::uint64_t hash) {
  return static_cast<double>(hash >> 11) * (1.0 / 9007199254740992.0);
}

}  // namespace superdyna::sim

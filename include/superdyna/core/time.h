#pragma once
// Time is an int64 count of nanoseconds everywhere (`t_ns`). Conversions from decimal seconds are
// exact (parsed from the text, not through a double), so TUM and EuRoC timestamps round-trip.

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace superdyna {

using TimeNs = std::int64_t;

inline constexpr TimeNs kNsPerSecond = 1'000'000'000;
inline constexpr TimeNs kNsPerMillisecond = 1'000'000;

inline double nsToSeconds(TimeNs t_ns) {
  return static_cast<double>(t_ns) * 1e-9;
}
/// Rounds to the nearest nanosecond.
TimeNs secondsToNs(double seconds);

/// Parses a decimal number of seconds ("1403636580.83856", "-0.5", "12") to nanoseconds exactly,
/// rounding digits beyond the ninth decimal to nearest. Also accepts exponent notation
/// ("1.037359e-01", as in KITTI times.txt) through a double. Returns nullopt when malformed.
std::optional<TimeNs> parseSecondsToNs(std::string_view text);

/// Formats nanoseconds as seconds with exactly nine decimals ("1403636580.838560000").
std::string formatNsAsSeconds(TimeNs t_ns);

/// Wall-clock milliseconds since `start` (stage timings).
double millisecondsSince(std::chrono::steady_clock::time_point start);

/// Half-open time interval [begin, end] of a data stream (both ends inclusive, as the samples).
struct TimeRange {
  TimeNs begin = 0;
  TimeNs end = 0;

  bool contains(TimeNs t_ns) const { return t_ns >= begin && t_ns <= end; }
  double durationSeconds() const { return nsToSeconds(end - begin); }
};

}  // namespace superdyna

#include "superdyna/core/time.h"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <limits>

namespace superdyna {

TimeNs secondsToNs(double seconds) {
  return static_cast<TimeNs>(std::llround(seconds * 1e9));
}

namespace {

/// The most whole seconds whose nanoseconds, with any fraction and its rounding, fit int64.
constexpr TimeNs kMaxWholeSeconds = std::numeric_limits<TimeNs>::max() / kNsPerSecond - 1;

bool isDigits(std::string_view s) {
  for (char c : s) {
    if (c < '0' || c > '9') return false;
  }
  return true;
}

std::optional<TimeNs> parseExponentSeconds(std::string_view text) {
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || ptr != text.data() + text.size() || !std::isfinite(value)) {
    return std::nullopt;
  }
  if (std::abs(value) > 9.2e9) return std::nullopt;  // would overflow int64 nanoseconds
  return secondsToNs(value);
}

}  // namespace

std::optional<TimeNs> parseSecondsToNs(std::string_view text) {
  if (text.empty()) return std::nullopt;
  if (text.find_first_of("eE") != std::string_view::npos) return parseExponentSeconds(text);
  bool negative = false;
  if (text.front() == '-' || text.front() == '+') {
    negative = text.front() == '-';
    text.remove_prefix(1);
  }
  const std::size_t dot = text.find('.');
  std::string_view whole = text.substr(0, dot);
  std::string_view frac = dot == std::string_view::npos ? std::string_view{} : text.substr(dot + 1);
  if ((whole.empty() && frac.empty()) || !isDigits(whole) || !isDigits(frac)) return std::nullopt;
  if (whole.size() > 10) return std::nullopt;  // > 9.2e9 s does not fit int64 nanoseconds

  TimeNs seconds = 0;
  for (char c : whole)
    seconds = seconds * 10 + (c - '0');
  if (seconds > kMaxWholeSeconds) return std::nullopt;
  TimeNs nanos = 0;
  for (std::size_t i = 0; i < 9; ++i) {
    nanos = nanos * 10 + (i < frac.size() ? frac[i] - '0' : 0);
  }
  if (frac.size() > 9 && frac[9] >= '5') ++nanos;  // round half up on the tenth decimal
  const TimeNs total = seconds * kNsPerSecond + nanos;
  return negative ? -total : total;
}

std::string formatNsAsSeconds(TimeNs t_ns) {
  const bool negative = t_ns < 0;
  const std::uint64_t magnitude =
      negative ? static_cast<std::uint64_t>(-(t_ns + 1)) + 1 : static_cast<std::uint64_t>(t_ns);
  return fmt::format("{}{}.{:09d}", negative ? "-" : "", magnitude / kNsPerSecond,
                     magnitude % kNsPerSecond);
}

double millisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

}  // namespace superdyna

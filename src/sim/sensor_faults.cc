#include "superdyna/sim/sensor_faults.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <string_view>

#include "superdyna/core/error.h"
#include "superdyna/sim/hash.h"

namespace superdyna::sim {

namespace {

double parseSeconds(std::string_view text, const std::string& option, const std::string& whole) {
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || ec != std::errc() || ptr != text.data() + text.size() ||
      !std::isfinite(value)) {
    throw OptionError(option, fmt::format("'{}' is not T0:T1 in seconds", whole));
  }
  return value;
}

void validateIntervals(const std::vector<FaultInterval>& intervals, const char* option) {
  for (const FaultInterval& interval : intervals) {
    if (!(interval.t0_s >= 0.0 && interval.t1_s > interval.t0_s)) {
      throw OptionError(option, fmt::format("interval {}:{} must have 0 <= T0 < T1", interval.t0_s,
                                            interval.t1_s));
    }
  }
}

}  // namespace

FaultInterval parseFaultInterval(const std::string& text, const std::string& option) {
  const std::size_t colon = text.find(':');
  if (colon == std::string::npos) {
    throw OptionError(option, fmt::format("'{}' is not T0:T1 in seconds", text));
  }
  const std::string_view view(text);
  FaultInterval interval{parseSeconds(view.substr(0, colon), option, text),
                         parseSeconds(view.substr(colon + 1), option, text)};
  validateIntervals({interval}, option.c_str());
  return interval;
}

void parseDropFrames(const std::string& text, SensorFaultOptions* faults) {
  const bool is_rate = text.find('.') != std::string::npos;
  if (is_rate) {
    double rate = 0.0;
    const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), rate);
    if (ec != std::errc() || ptr != text.data() + text.size() || !(rate >= 0.0 && rate < 1.0)) {
      throw OptionError("--drop-frames",
                        fmt::format("'{}' is neither a rate in [0, 1) nor a list of frame "
                                    "indices",
                                    text));
    }
    faults->drop_frame_rate = rate;
    return;
  }
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t comma = std::min(text.find(',', start), text.size());
    std::size_t index = 0;
    const char* first = text.data() + start;
    const char* last = text.data() + comma;
    const auto [ptr, ec] = std::from_chars(first, last, index);
    if (first == last || ec != std::errc() || ptr != last) {
      throw OptionError("--drop-frames",
                        fmt::format("'{}' is neither a rate in [0, 1) nor a list of frame "
                                    "indices",
                                    text));
    }
    faults->drop_frames.push_back(index);
    start = comma + 1;
  }
}

bool inAnyInterval(const std::vector<FaultInterval>& intervals, double t_s) {
  return std::any_of(intervals.begin(), intervals.end(),
                     [&](const FaultInterval& interval) { return interval.contains(t_s); });
}

bool SensorFaultOptions::any() const {
  return drop_frame_rate > 0.0 || !drop_frames.empty() || !imu_gaps.empty() || !imu_nan.empty() ||
         !black_frames.empty() || !overexposed_frames.empty() || !missing_cam1.empty() ||
         !repeated_rows.empty() || !swapped_rows.empty() || !imu_saturated.empty() ||
         imu_time_offset_s != 0.0;
}

void SensorFaultOptions::validate() const {
  if (!(drop_frame_rate >= 0.0 && drop_frame_rate < 1.0)) {
    throw OptionError("--drop-frames", "the rate must be in [0, 1)");
  }
  if (std::find(drop_frames.begin(), drop_frames.end(), 0) != drop_frames.end()) {
    throw OptionError("--drop-frames", "frame 0 cannot be dropped: the sequence starts with it");
  }
  if (!(std::abs(imu_time_offset_s) < 1.0)) {
    throw OptionError("--time-offset", "must be a number of seconds in (-1, 1)");
  }
  validateIntervals(imu_gaps, "--imu-gap");
  validateIntervals(imu_nan, "--imu-nan");
  validateIntervals(black_frames, "--black-frames");
  validateIntervals(overexposed_frames, "--overexposed-frames");
  validateIntervals(missing_cam1, "--missing-cam1");
  validateIntervals(repeated_rows, "--repeat-timestamps");
  validateIntervals(swapped_rows, "--swap-timestamps");
  validateIntervals(imu_saturated, "--imu-saturate");
}

bool SensorFaultOptions::dropsFrame(std::size_t index, std::uint64_t seed) const {
  if (std::find(drop_frames.begin(), drop_frames.end(), index) != drop_frames.end()) return true;
  if (index == 0 || !(drop_frame_rate > 0.0)) return false;
  return unitFromHash(mix64(mix64(seed ^ 0xd5095ULL) + index)) < drop_frame_rate;
}

std::vector<std::string> faultyRowOrder(const std::vector<TimedRow>& rows,
                                        const SensorFaultOptions& faults) {
  std::vector<std::string> out;
  out.reserve(rows.size());
  const auto swapped = [&](std::size_t k) {
    return k + 1 < rows.size() && inAnyInterval(faults.swapped_rows, rows[k].t_s) &&
           inAnyInterval(faults.swapped_rows, rows[k + 1].t_s);
  };
  const auto write = [&](const TimedRow& row) {
    out.push_back(row.text);
    if (inAnyInterval(faults.repeated_rows, row.t_s)) out.push_back(row.text);
  };
  for (std::size_t k = 0; k < rows.size(); ++k) {
    if (swapped(k)) {
      write(rows[k + 1]);
      write(rows[k]);
      ++k;
    } else {
      write(rows[k]);
    }
  }
  return out;
}

}  // namespace superdyna::sim

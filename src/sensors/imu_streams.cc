#include "superdyna/sensors/imu_streams.h"

#include <fmt/format.h>

#include <algorithm>

#include "superdyna/core/error.h"

namespace superdyna::sensors {

namespace {

void requireTimeOrder(const std::vector<ImuSample>& samples, const char* stream) {
  const auto later =
      std::adjacent_find(samples.begin(), samples.end(),
                         [](const ImuSample& a, const ImuSample& b) { return b.t_ns < a.t_ns; });
  if (later == samples.end()) return;
  throw InputError(fmt::format("{} sample {} is stamped {} ns, after the next one ({} ns)", stream,
                               later - samples.begin(), later->t_ns, (later + 1)->t_ns));
}

}  // namespace

MergedImu mergeImuStreams(const std::vector<ImuSample>& accel, const std::vector<ImuSample>& gyro,
                          TimeNs max_accel_gap_ns) {
  requireTimeOrder(accel, "accelerometer");
  requireTimeOrder(gyro, "gyroscope");
  MergedImu merged;
  merged.samples.reserve(gyro.size());
  auto after = accel.begin();  // first accel sample later than the gyroscope sample
  for (const ImuSample& g : gyro) {
    after = std::find_if(after, accel.end(), [&](const ImuSample& a) { return a.t_ns > g.t_ns; });
    if (after == accel.begin() ||
        (after == accel.end() && (accel.empty() || accel.back().t_ns != g.t_ns))) {
      ++merged.outside;
      continue;
    }
    const ImuSample& a0 = *std::prev(after);
    ImuSample sample{.t_ns = g.t_ns, .gyro = g.gyro, .accel = a0.accel};
    if (a0.t_ns != g.t_ns) {
      const ImuSample& a1 = *after;
      if (a1.t_ns - a0.t_ns > max_accel_gap_ns) {
        ++merged.in_gaps;
        continue;
      }
      const double s =
          static_cast<double>(g.t_ns - a0.t_ns) / static_cast<double>(a1.t_ns - a0.t_ns);
      sample.accel = (1.0 - s) * a0.accel + s * a1.accel;
    }
    merged.samples.push_back(sample);
  }
  return merged;
}

}  // namespace superdyna::sensors

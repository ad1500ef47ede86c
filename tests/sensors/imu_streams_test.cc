#include "superdyna/sensors/imu_streams.h"

#include <gtest/gtest.h>

#include "superdyna/core/error.h"

namespace superdyna::sensors {
namespace {

constexpr TimeNs kMs = kNsPerMillisecond;

/// A linear motion signal: accel (t, 2t, -t) and gyro (t, 0, 1) at t in seconds.
ImuSample accelAt(TimeNs t_ns) {
  const double t = static_cast<double>(t_ns) * 1e-9;
  return {.t_ns = t_ns, .gyro = Eigen::Vector3d::Constant(99.0), .accel = {t, 2.0 * t, -t}};
}
ImuSample gyroAt(TimeNs t_ns) {
  const double t = static_cast<double>(t_ns) * 1e-9;
  return {.t_ns = t_ns, .gyro = {t, 0.0, 1.0}, .accel = Eigen::Vector3d::Constant(99.0)};
}

TEST(MergeImuStreams, OneSamplePerGyroSampleWithTheAccelerationInterpolatedLinearly) {
  std::vector<ImuSample> accel, gyro;
  for (TimeNs t = 0; t <= 1000 * kMs; t += 16 * kMs)  // 62.5 Hz
    accel.push_back(accelAt(t));
  for (TimeNs t = 3 * kMs; t <= 1100 * kMs; t += 5 * kMs)  // 200 Hz, ends after the accel
    gyro.push_back(gyroAt(t));
  const MergedImu merged = mergeImuStreams(accel, gyro);
  // accel spans 0 .. 992 ms: gyro samples at 3, 8, ..., 988 ms are inside (198 of them).
  ASSERT_EQ(merged.samples.size(), 198u);
  EXPECT_EQ(merged.outside, gyro.size() - 198u);
  EXPECT_EQ(merged.in_gaps, 0u);
  for (std::size_t i = 0; i < merged.samples.size(); ++i) {
    const ImuSample& s = merged.samples[i];
    EXPECT_EQ(s.t_ns, gyro[i].t_ns);
    EXPECT_EQ(s.gyro, gyro[i].gyro);  // the gyroscope's own values, never the accel messages'
    EXPECT_LT((s.accel - accelAt(s.t_ns).accel).norm(), 1e-12) << "at " << s.t_ns;
  }
}

TEST(MergeImuStreams, StampsSharedWithAnAccelSampleTakeItsValueAndGapsAreNotBridged) {
  std::vector<ImuSample> accel = {accelAt(0), accelAt(10 * kMs), accelAt(300 * kMs),
                                  accelAt(310 * kMs)};
  accel[1].accel = {5.0, 5.0, 5.0};
  const std::vector<ImuSample> gyro = {gyroAt(10 * kMs), gyroAt(150 * kMs), gyroAt(310 * kMs)};
  const MergedImu merged = mergeImuStreams(accel, gyro, 100 * kMs);
  ASSERT_EQ(merged.samples.size(), 2u);
  EXPECT_EQ(merged.samples[0].accel, Eigen::Vector3d(5.0, 5.0, 5.0));
  EXPECT_EQ(merged.samples[1].t_ns, 310 * kMs);  // the last accel stamp itself is inside
  EXPECT_EQ(merged.samples[1].accel, accelAt(310 * kMs).accel);
  EXPECT_EQ(merged.in_gaps, 1u);  // 150 ms lies in the 290 ms gap
  EXPECT_EQ(merged.outside, 0u);
}

TEST(MergeImuStreams, StreamsOutOfTimeOrderAreAnErrorNamingTheStreamAndSample) {
  const std::vector<ImuSample> accel = {accelAt(0), accelAt(20 * kMs), accelAt(10 * kMs)};
  const std::vector<ImuSample> gyro = {gyroAt(5 * kMs)};
  try {
    mergeImuStreams(accel, gyro);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("accelerometer sample 1"), std::string::npos) << e.what();
  }
  EXPECT_THROW(mergeImuStreams(gyro, accel), InputError);
  EXPECT_TRUE(mergeImuStreams({}, gyro).samples.empty());
}

}  // namespace
}  // namespace superdyna::sensors

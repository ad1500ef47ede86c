#include "superdyna/io/live_frame_assembler.h"

#include <gtest/gtest.h>

#include "superdyna/io/dataset_source.h"

namespace superdyna::io {
namespace {

constexpr TimeNs kMs = kNsPerMillisecond;

sensors::ImuSample imuAt(TimeNs t_ns) {
  return {.t_ns = t_ns, .gyro = Eigen::Vector3d::Constant(1e-9 * t_ns), .accel = {0, 0, 9.81}};
}

cv::Mat imageWith(int value) {
  return cv::Mat(4, 4, CV_8UC1, cv::Scalar(value));
}

std::vector<sensors::FrameBundle> drain(LiveFrameAssembler& assembler) {
  std::vector<sensors::FrameBundle> out;
  while (auto frame = assembler.next())
    out.push_back(std::move(*frame));
  return out;
}

TEST(LiveFrameAssembler, GivesTheFramesAndImuIntervalsOfADatasetSourceWhateverTheArrivalOrder) {
  // 200 Hz IMU, 20 Hz stereo; images arrive 30 ms late, the right one before the left one.
  std::vector<sensors::ImuSample> imu;
  for (TimeNs t = 1000 * kMs; t <= 2000 * kMs; t += 5 * kMs)
    imu.push_back(imuAt(t));
  LiveFrameAssembler assembler({});
  std::vector<sensors::FrameBundle> frames;
  std::size_t next_imu = 0;
  for (TimeNs t = 1010 * kMs; t <= 1900 * kMs; t += 50 * kMs) {
    while (next_imu < imu.size() && imu[next_imu].t_ns <= t + 30 * kMs)
      assembler.addImu(imu[next_imu++]);
    assembler.addImage(1, t + kMs, imageWith(2));  // right stamped 1 ms later
    assembler.addImage(0, t, imageWith(1));
    for (auto& frame : drain(assembler))
      frames.push_back(std::move(frame));
  }
  while (next_imu < imu.size())
    assembler.addImu(imu[next_imu++]);
  for (auto& frame : drain(assembler))
    frames.push_back(std::move(frame));

  ASSERT_EQ(frames.size(), 18u);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const sensors::FrameBundle& frame = frames[i];
    EXPECT_EQ(frame.index, i);
    EXPECT_EQ(frame.t_ns, 1010 * kMs + static_cast<TimeNs>(i) * 50 * kMs);  // the left stamp
    EXPECT_EQ(frame.image0.at<std::uint8_t>(0, 0), 1);
    EXPECT_EQ(frame.image1.at<std::uint8_t>(0, 0), 2);
    const TimeNs t_prev = i == 0 ? frame.t_ns : frames[i - 1].t_ns;
    const std::vector<sensors::ImuSample> expected = bracketingImu(imu, t_prev, frame.t_ns);
    ASSERT_EQ(frame.imu.size(), expected.size()) << "frame " << i;
    for (std::size_t k = 0; k < expected.size(); ++k)
      EXPECT_EQ(frame.imu[k].t_ns, expected[k].t_ns);
  }
  EXPECT_EQ(assembler.counters().frames, 18u);
  EXPECT_EQ(assembler.counters().images_unpaired, 0u);
  EXPECT_EQ(assembler.pending(), 0u);
}

TEST(LiveFrameAssembler, AFrameWaitsUntilTheImuCoversItsTime) {
  LiveFrameAssembler assembler({.stereo = false});
  assembler.addImu(imuAt(100 * kMs));
  assembler.addImage(0, 120 * kMs, imageWith(1));
  EXPECT_FALSE(assembler.next().has_value());
  assembler.addImu(imuAt(119 * kMs));
  EXPECT_FALSE(assembler.next().has_value());
  assembler.addImu(imuAt(121 * kMs));
  const auto frame = assembler.next();
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->imu.back().t_ns, 121 * kMs);
}

TEST(LiveFrameAssembler, LateDuplicateAndUnpairedMessagesAreCountedNotUsed) {
  LiveAssemblerOptions options;
  options.max_wait_ns = 200 * kMs;
  LiveFrameAssembler assembler(options);
  for (TimeNs t = 0; t <= 2000 * kMs; t += 5 * kMs)
    assembler.addImu(imuAt(t));
  assembler.addImu(imuAt(1000 * kMs));  // IMU out of order
  EXPECT_EQ(assembler.counters().imu_out_of_order, 1u);

  assembler.addImage(0, 100 * kMs, imageWith(1));
  assembler.addImage(1, 100 * kMs, imageWith(2));
  ASSERT_TRUE(assembler.next().has_value());
  assembler.addImage(0, 100 * kMs, imageWith(1));  // at the stamp of a frame handed out
  assembler.addImage(0, 50 * kMs, imageWith(1));   // older
  EXPECT_EQ(assembler.counters().images_out_of_order, 2u);

  assembler.addImage(0, 150 * kMs, imageWith(1));  // its right image never comes
  assembler.addImage(1, 170 * kMs, imageWith(2));  // 20 ms off: not a pair
  assembler.addImage(0, 200 * kMs, imageWith(1));
  assembler.addImage(0, 200 * kMs, imageWith(1));  // repeated stamp
  EXPECT_EQ(assembler.counters().duplicate_images, 1u);
  EXPECT_FALSE(assembler.next().has_value());
  assembler.addImage(1, 200 * kMs, imageWith(2));
  const auto frame = assembler.next();
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->t_ns, 200 * kMs);
  // Handing out the 200 ms frame gave up the 150 ms left and 170 ms right images.
  EXPECT_EQ(assembler.counters().images_unpaired, 2u);
}

TEST(LiveFrameAssembler, FramesTheImuNeverReachesAreDroppedAfterTheWait) {
  LiveAssemblerOptions options;
  options.stereo = false;
  options.max_wait_ns = 200 * kMs;
  LiveFrameAssembler assembler(options);
  assembler.addImu(imuAt(0));
  assembler.addImu(imuAt(60 * kMs));
  for (TimeNs t = 50 * kMs; t <= 350 * kMs; t += 50 * kMs)
    assembler.addImage(0, t, imageWith(1));
  // The IMU stopped at 60 ms: the 50 ms frame is ready, 100 ms and later wait; an image more than
  // 200 ms newer than a waiting frame drops it.
  const auto frame = assembler.next();
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->t_ns, 50 * kMs);
  EXPECT_FALSE(assembler.next().has_value());
  EXPECT_EQ(assembler.counters().frames_without_imu, 1u);  // 100 ms (< 350 - 200)
  EXPECT_EQ(assembler.pending(), 5u);                      // 150 ... 350 ms
  assembler.addImage(0, 400 * kMs, imageWith(1));
  EXPECT_EQ(assembler.counters().frames_without_imu, 2u);  // and 150 ms (< 400 - 200)

  LiveFrameAssembler without_imu({.stereo = false, .inertial = false});
  without_imu.addImage(0, 10 * kMs, imageWith(1));
  const auto visual = without_imu.next();
  ASSERT_TRUE(visual.has_value());
  EXPECT_TRUE(visual->imu.empty());
}

TEST(LiveFrameAssembler, ASkippedFramesImuIsCarriedIntoTheNextFrame) {
  std::vector<sensors::ImuSample> imu;
  for (TimeNs t = 0; t <= 200 * kMs; t += 5 * kMs)
    imu.push_back(imuAt(t));
  LiveFrameAssembler assembler({.stereo = false});
  for (const sensors::ImuSample& sample : imu)
    assembler.addImu(sample);
  for (const TimeNs t : {TimeNs{50 * kMs}, TimeNs{102 * kMs}, TimeNs{150 * kMs}})
    assembler.addImage(0, t, imageWith(1));
  const std::vector<sensors::FrameBundle> frames = drain(assembler);
  ASSERT_EQ(frames.size(), 3u);
  sensors::FrameBundle next = frames[2];
  carrySkippedImu(frames[1], next);  // the pipeline sees 50 ms, then 150 ms
  const std::vector<sensors::ImuSample> expected = bracketingImu(imu, 50 * kMs, 150 * kMs);
  ASSERT_EQ(next.imu.size(), expected.size());
  for (std::size_t k = 0; k < expected.size(); ++k)
    EXPECT_EQ(next.imu[k].t_ns, expected[k].t_ns);
}

}  // namespace
}  // namespace superdyna::io

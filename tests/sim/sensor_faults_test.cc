#include "superdyna/sim/sensor_faults.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>

#include "superdyna/core/error.h"
#include "superdyna/io/euroc_dataset.h"
#include "superdyna/io/text_table.h"
#include "superdyna/sim/sequence_generator.h"
#include "support/test_support.h"

namespace superdyna::sim {
namespace {

namespace fs = std::filesystem;

bool anyContains(const std::vector<std::string>& texts, const std::string& fragment) {
  return std::any_of(texts.begin(), texts.end(), [&](const std::string& text) {
    return text.find(fragment) != std::string::npos;
  });
}

TEST(SensorFaults, ParsesIntervalsRatesAndFrameLists) {
  const FaultInterval interval = parseFaultInterval("1.5:2", "--imu-gap");
  EXPECT_DOUBLE_EQ(interval.t0_s, 1.5);
  EXPECT_DOUBLE_EQ(interval.t1_s, 2.0);
  EXPECT_TRUE(interval.contains(1.5));
  EXPECT_FALSE(interval.contains(2.0));  // half-open
  EXPECT_THROW(parseFaultInterval("2:1", "--imu-gap"), OptionError);
  EXPECT_THROW(parseFaultInterval("1.5", "--imu-gap"), OptionError);
  EXPECT_THROW(parseFaultInterval("a:2", "--imu-nan"), OptionError);

  SensorFaultOptions list;
  parseDropFrames("10,11,40", &list);
  EXPECT_EQ(list.drop_frames, (std::vector<std::size_t>{10, 11, 40}));
  EXPECT_TRUE(list.dropsFrame(11, 1));
  EXPECT_FALSE(list.dropsFrame(12, 1));
  SensorFaultOptions rate;
  parseDropFrames("0.2", &rate);
  EXPECT_DOUBLE_EQ(rate.drop_frame_rate, 0.2);
  int dropped = 0;
  for (std::size_t k = 0; k < 10000; ++k)
    dropped += rate.dropsFrame(k, 7) ? 1 : 0;
  EXPECT_NEAR(dropped, 2000, 150);  // binomial std 40
  EXPECT_FALSE(rate.dropsFrame(0, 7));
  EXPECT_EQ(rate.dropsFrame(123, 7), rate.dropsFrame(123, 7));
  SensorFaultOptions bad;
  EXPECT_THROW(parseDropFrames("1.5", &bad), OptionError);
  EXPECT_THROW(parseDropFrames("3,x", &bad), OptionError);
  bad.drop_frames = {0};
  EXPECT_THROW(bad.validate(), OptionError);
  SensorFaultOptions offset;
  offset.imu_time_offset_s = 1.5;
  EXPECT_THROW(offset.validate(), OptionError);
  SensorFaultOptions reversed;
  reversed.missing_cam1 = {{2.0, 1.0}};
  test::expectError<OptionError>([&] { reversed.validate(); }, {"--missing-cam1"});
  SensorFaultOptions white;
  white.overexposed_frames = {{-1.0, 1.0}};
  test::expectError<OptionError>([&] { white.validate(); }, {"--overexposed-frames"});
  EXPECT_TRUE(white.any());
}

/// A 1.5 s indoor flight with frames 3 and 4 dropped, IMU rows missing over [0.5, 0.75) s and nan
/// over [1.0, 1.1) s, black images over [1.2, 1.3) s, white ones over [0.2, 0.3) s, no cam1
/// over [0.8, 0.9) s, IMU timestamps 12.5 ms late.
TEST(SensorFaults, AreWrittenAsRealSensorsProduceThem) {
  const test::ScratchDir dir("sensor_faults");
  SimulationOptions options;
  options.output_dir = dir.path();
  options.overwrite = true;
  options.motion.duration_s = 1.5;
  options.world.scene = SceneType::kIndoor;
  options.world.dynamic = DynamicLevel::kNone;
  options.landmark_count = 0;
  options.faults.drop_frames = {3, 4};
  options.faults.imu_gaps = {{0.5, 0.75}};
  options.faults.imu_nan = {{1.0, 1.1}};
  options.faults.black_frames = {{1.2, 1.3}};
  options.faults.overexposed_frames = {{0.2, 0.3}};
  options.faults.missing_cam1 = {{0.8, 0.9}};
  options.faults.imu_time_offset_s = 0.0125;
  const SimulationSummary summary = generateSequence(options);
  EXPECT_EQ(summary.frames, 29);  // 31 at 20 Hz, two dropped

  const fs::path mav0 = dir.path() / "mav0";
  const std::vector<io::TextRow> cam0 =
      io::readTextRows(mav0 / "cam0/data.csv", io::Delimiter::kComma);
  const std::vector<io::TextRow> cam1 =
      io::readTextRows(mav0 / "cam1/data.csv", io::Delimiter::kComma);
  ASSERT_EQ(cam0.size(), 29u);
  ASSERT_EQ(cam1.size(), 27u);  // 0.80 and 0.85 s missing
  for (const io::TextRow& row : cam1) {
    const double t_s = nsToSeconds(std::stoll(row.fields[0]) - std::stoll(cam0[0].fields[0]));
    EXPECT_FALSE(t_s >= 0.8 - 1e-9 && t_s < 0.9 - 1e-9) << "cam1 row at " << t_s;
  }
  const TimeNs t0 = std::stoll(cam0[0].fields[0]);
  EXPECT_EQ(std::stoll(cam0[3].fields[0]) - t0, secondsToNs(0.25));  // frame 5 follows frame 2
  for (const io::TextRow& row : cam0) {
    const double t_s = nsToSeconds(std::stoll(row.fields[0]) - t0);
    const cv::Mat image =
        cv::imread((mav0 / "cam0/data" / row.fields[1]).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(image.empty());
    const bool black = t_s >= 1.2 - 1e-9 && t_s < 1.3 - 1e-9;
    const bool white = t_s >= 0.2 - 1e-9 && t_s < 0.3 - 1e-9;
    EXPECT_EQ(cv::countNonZero(image) == 0, black) << "t = " << t_s;
    EXPECT_EQ(cv::countNonZero(image != 255) == 0, white) << "t = " << t_s;
  }
  const std::vector<io::TextRow> imu =
      io::readTextRows(mav0 / "imu0/data.csv", io::Delimiter::kComma);
  EXPECT_EQ(std::stoll(imu.front().fields[0]) - t0, secondsToNs(0.0125));  // IMU stamped late
  int nan_rows = 0;
  for (const io::TextRow& row : imu) {
    const double t_s = nsToSeconds(std::stoll(row.fields[0]) - t0) - 0.0125;
    EXPECT_FALSE(t_s >= 0.5 + 1e-9 && t_s < 0.75 - 1e-9) << "row in the gap at " << t_s;
    if (row.fields[1] == "nan") ++nan_rows;
  }
  EXPECT_NEAR(nan_rows, 20, 1);  // 0.1 s at 200 Hz

  // The reader skips the nan rows and reports them, the dropped frames and the gaps.
  const io::EurocDataset dataset = io::EurocDataset::open(dir.path());
  EXPECT_EQ(dataset.stereoFrames().size(), 27u);  // the frames without cam1 are mono only
  EXPECT_EQ(dataset.monoFrames().size(), 29u);
  EXPECT_TRUE(anyContains(dataset.warnings(), "2 frame(s) have no cam1 frame"));
  for (const sensors::ImuSample& sample : dataset.imu())
    ASSERT_TRUE(sample.gyro.allFinite() && sample.accel.allFinite());
  EXPECT_TRUE(anyContains(dataset.warnings(), "with nan or inf values skipped"));
  EXPECT_TRUE(anyContains(dataset.warnings(), "about 2 dropped frame(s) in 1 time step(s)"));
  EXPECT_TRUE(anyContains(dataset.warnings(), "2 gap(s) longer than 5 nominal periods"));
}

TEST(SensorFaults, RowOrderRepeatsAndSwapsOnlyInsideTheirIntervals) {
  std::vector<TimedRow> rows;
  for (int k = 0; k < 8; ++k)
    rows.push_back({0.1 * k, std::to_string(k)});
  SensorFaultOptions faults;
  faults.repeated_rows = {{0.05, 0.15}};  // row 1
  faults.swapped_rows = {{0.25, 0.65}};   // rows 3-6: (3, 4) and (5, 6) swapped
  EXPECT_EQ(faultyRowOrder(rows, faults),
            (std::vector<std::string>{"0", "1", "1", "2", "4", "3", "6", "5", "7"}));
  faults.swapped_rows = {{0.25, 0.45}};   // rows 3 and 4 only
  faults.repeated_rows = {{0.35, 0.45}};  // row 4, written twice where it lands
  EXPECT_EQ(faultyRowOrder(rows, faults),
            (std::vector<std::string>{"0", "1", "2", "4", "4", "3", "5", "6", "7"}));
  EXPECT_EQ(faultyRowOrder(rows, SensorFaultOptions()).size(), rows.size());
  faults.imu_saturated = {{1.0, 0.5}};
  test::expectError<OptionError>([&] { faults.validate(); }, {"--imu-saturate"});
}

/// Repeated and swapped camera and IMU rows over [0.3, 0.5) s, saturated IMU rows over
/// [0.8, 0.9) s: the reader restores the clean sequence's frames and IMU samples (less the
/// saturated ones) and reports each fault.
TEST(SensorFaults, RepeatedSwappedAndSaturatedRowsAreRepairedOrSkippedByTheReader) {
  const auto simulate = [](const fs::path& out, const SensorFaultOptions& faults) {
    SimulationOptions options;
    options.output_dir = out;
    options.overwrite = true;
    options.motion.duration_s = 1.0;
    options.world.scene = SceneType::kIndoor;
    options.world.dynamic = DynamicLevel::kNone;
    options.landmark_count = 0;
    options.faults = faults;
    generateSequence(options);
    return io::EurocDataset::open(out);
  };
  const test::ScratchDir clean_dir("sensor_faults_clean"), faulty_dir("sensor_faults_rows");
  const io::EurocDataset clean = simulate(clean_dir.path(), {});
  SensorFaultOptions faults;
  faults.repeated_rows = {{0.3, 0.4}};
  faults.swapped_rows = {{0.4, 0.5}};
  faults.imu_saturated = {{0.8, 0.9}};
  const io::EurocDataset faulty = simulate(faulty_dir.path(), faults);

  ASSERT_EQ(faulty.stereoFrames().size(), clean.stereoFrames().size());
  for (std::size_t k = 0; k < clean.stereoFrames().size(); ++k)
    EXPECT_EQ(faulty.stereoFrames()[k].t_ns, clean.stereoFrames()[k].t_ns);
  const TimeNs t0 = clean.stereoFrames().front().t_ns;
  const auto saturatedTime = [&](TimeNs t) {
    return t - t0 >= secondsToNs(0.8) && t - t0 < secondsToNs(0.9);
  };
  std::size_t kept = 0;
  for (const sensors::ImuSample& sample : clean.imu()) {
    if (saturatedTime(sample.t_ns)) continue;
    ASSERT_LT(kept, faulty.imu().size());
    EXPECT_EQ(faulty.imu()[kept].t_ns, sample.t_ns);
    EXPECT_EQ(faulty.imu()[kept].accel, sample.accel);
    ++kept;
  }
  EXPECT_EQ(faulty.imu().size(), kept);
  EXPECT_NEAR(static_cast<double>(clean.imu().size() - kept), 20.0, 1.0);  // 0.1 s at 200 Hz
  const auto& warnings = faulty.warnings();
  EXPECT_TRUE(
      anyContains(warnings, "cam0/data.csv: 2 row(s) repeating an earlier row's timestamp"));
  EXPECT_TRUE(anyContains(warnings, "cam1/data.csv: 1 row(s) out of time order"));
  EXPECT_TRUE(
      anyContains(warnings, "imu0/data.csv: 20 row(s) repeating an earlier row's timestamp"));
  EXPECT_TRUE(anyContains(warnings, "imu0/data.csv: 10 row(s) out of time order"));
  EXPECT_TRUE(anyContains(warnings, "row(s) at the sensor's range (saturated"));
  EXPECT_NEAR(faulty.imuCalibration()->accelerometer_range, 16.0 * 9.80665, 1e-6);
}

}  // namespace
}  // namespace superdyna::sim

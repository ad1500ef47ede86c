#include "superdyna/io/euroc_dataset.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <functional>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "superdyna/core/error.h"
#include "support/test_support.h"

namespace superdyna::io {
namespace {

namespace fs = std::filesystem;
using test::readFile;
using test::ScratchDir;
using test::writeFile;

constexpr const char* kSequence = "data/euroc/V1_01_easy_micro";
constexpr TimeNs kFirstFrameNs = 1403715273262142976;
constexpr TimeNs kSecondFrameNs = 1403715273312143104;
constexpr TimeNs kLastFrameNs = 1403715277962142976;  // last row of cam0/data.csv
constexpr TimeNs kFirstImuNs = 1403715273262142976;
constexpr TimeNs kLastImuNs = 1403715418857143040;  // last row of imu0/data.csv
constexpr TimeNs kLastGroundTruthNs = 1403715417962142976;

bool anyContains(const std::vector<std::string>& texts, const std::string& fragment) {
  return std::any_of(texts.begin(), texts.end(), [&](const std::string& text) {
    return text.find(fragment) != std::string::npos;
  });
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> result;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    result.push_back(line);
  return result;
}

std::string joined(const std::vector<std::string>& text_lines) {
  std::string text;
  for (const std::string& line : text_lines)
    text += line + "\n";
  return text;
}

/// Rewrites line `number` (1-based) of `file`; an empty `text` deletes the line.
void editLine(const fs::path& file, std::size_t number, const std::string& text) {
  std::vector<std::string> content = lines(readFile(file));
  ASSERT_LE(number, content.size());
  if (text.empty()) {
    content.erase(content.begin() + static_cast<std::ptrdiff_t>(number - 1));
  } else {
    content[number - 1] = text;
  }
  writeFile(file, joined(content));
}

/// Copies the first `count` lines of a text file (the header is line 1).
void copyHead(const fs::path& from, const fs::path& to, std::size_t count) {
  std::vector<std::string> content = lines(readFile(from));
  content.resize(std::min(count, content.size()));
  writeFile(to, joined(content));
}

/// A small copy of the excerpt: calibration files, the first `frames` rows of each camera with
/// their images, the first 100 IMU rows (0.5 s) and the first 10 ground-truth rows. Files are
/// rewritten rather than copied so that they are writable (the shared ones are read-only).
fs::path makeSmallCopy(const fs::path& sequence, const ScratchDir& dir, std::size_t frames = 3) {
  const fs::path from = sequence / "mav0";
  const fs::path to = dir / "mav0";
  for (const char* camera : {"cam0", "cam1"}) {
    fs::create_directories(to / camera / "data");
    writeFile(to / camera / "sensor.yaml", readFile(from / camera / "sensor.yaml"));
    copyHead(from / camera / "data.csv", to / camera / "data.csv", frames + 1);
    for (const std::string& line : lines(readFile(to / camera / "data.csv"))) {
      if (line.front() == '#') continue;
      const std::string name = line.substr(line.find(',') + 1);
      writeFile(to / camera / "data" / name, readFile(from / camera / "data" / name));
    }
  }
  fs::create_directories(to / "imu0");
  writeFile(to / "imu0" / "sensor.yaml", readFile(from / "imu0" / "sensor.yaml"));
  copyHead(from / "imu0" / "data.csv", to / "imu0" / "data.csv", 101);
  fs::create_directories(to / "state_groundtruth_estimate0");
  copyHead(from / "state_groundtruth_estimate0" / "data.csv",
           to / "state_groundtruth_estimate0" / "data.csv", 11);
  return dir.path();
}

TEST(EurocDatasetTest, ReadsTheRealExcerpt) {
  SUPERDYNA_REQUIRE_SHARED(sequence, kSequence);
  const EurocDataset dataset = EurocDataset::open(sequence);
  EXPECT_EQ(dataset.root(), sequence / "mav0");
  ASSERT_TRUE(dataset.isStereo());
  ASSERT_TRUE(dataset.hasImu());
  ASSERT_TRUE(dataset.hasGroundTruth());

  const auto& stereo = dataset.stereoFrames();
  ASSERT_EQ(stereo.size(), 95u);
  EXPECT_EQ(stereo.front().t_ns, kFirstFrameNs);
  EXPECT_EQ(stereo.back().t_ns, kLastFrameNs);
  EXPECT_EQ(stereo.front().cam0, sequence / "mav0/cam0/data/1403715273262142976.png");
  EXPECT_EQ(stereo.front().cam1, sequence / "mav0/cam1/data/1403715273262142976.png");
  EXPECT_EQ(dataset.monoFrames().size(), 95u);
  EXPECT_EQ(dataset.cam0TimeRange().begin, kFirstFrameNs);
  EXPECT_EQ(dataset.cam0TimeRange().end, kLastFrameNs);

  // cam1/data.csv lists 4 frames after the last cam0 frame, whose images are not in the excerpt:
  // they are reported, not used.
  EXPECT_EQ(dataset.cam1TimeRange()->end, 1403715278162142976);
  ASSERT_EQ(dataset.warnings().size(), 1u);
  EXPECT_TRUE(anyContains(dataset.warnings(), "cam1/data.csv: 4 frame(s) have no cam0 frame"));
  EXPECT_TRUE(anyContains(dataset.warnings(), "line 97"));
  EXPECT_TRUE(anyContains(dataset.warnings(), "4 of their images do not exist"));

  EXPECT_EQ(dataset.cam0Calibration().fx, 458.654);
  EXPECT_EQ(dataset.cam1Calibration()->cx, 379.999);
  EXPECT_EQ(dataset.imuCalibration()->gyroscope_noise_density, 1.6968e-04);
  EXPECT_EQ(dataset.imuCalibration()->accelerometer_random_walk, 3.0e-3);

  // The IMU runs far longer than the images: 29,120 samples at 200 Hz over 145.6 s.
  const auto& imu = dataset.imu();
  ASSERT_EQ(imu.size(), 29120u);
  EXPECT_EQ(imu.front().t_ns, kFirstImuNs);
  EXPECT_EQ(imu.back().t_ns, kLastImuNs);
  EXPECT_NEAR(nsToSeconds(imu.front().t_ns - 1403715000 * kNsPerSecond), 273.26, 0.01);
  EXPECT_NEAR(nsToSeconds(imu.back().t_ns - 1403715000 * kNsPerSecond), 418.86, 0.01);
  EXPECT_DOUBLE_EQ(imu.front().gyro.y(), 0.017453292519943295);
  EXPECT_DOUBLE_EQ(imu.front().accel.x(), 9.0874956666666655);
  EXPECT_DOUBLE_EQ(imu.back().accel.z(), -3.2035056666666666);
  EXPECT_EQ(dataset.imuTimeRange()->begin, kFirstImuNs);
  EXPECT_NEAR(dataset.imuTimeRange()->durationSeconds(), 145.595, 1e-3);

  // 50 ms between frames at 200 Hz: 11 samples, both frame times included.
  const auto between = dataset.imuBetween(stereo[0].t_ns, stereo[1].t_ns);
  ASSERT_EQ(between.size(), 11u);
  EXPECT_EQ(between.front().t_ns, kFirstFrameNs);
  EXPECT_EQ(between.back().t_ns, kSecondFrameNs);
  EXPECT_EQ(dataset.imuBetween(stereo[0].t_ns + 1, stereo[1].t_ns - 1).size(), 9u);
  EXPECT_TRUE(dataset.imuBetween(stereo[1].t_ns, stereo[0].t_ns).empty());
  EXPECT_EQ(dataset.imuBetween(0, kFirstImuNs).size(), 1u);
  EXPECT_EQ(dataset.framesWithImuCoverage().size(), 95u);
  EXPECT_EQ(dataset.monoFramesWithImuCoverage().size(), 95u);
  EXPECT_FALSE(dataset.hasImuCoverage(kFirstImuNs - 1));

  const auto& truth = dataset.groundTruth();
  ASSERT_EQ(truth.size(), 2895u);
  EXPECT_TRUE(dataset.groundTruthHasVelocityAndBiases());
  EXPECT_EQ(truth.front().t_ns, kFirstFrameNs);
  EXPECT_EQ(truth.back().t_ns, kLastGroundTruthNs);
  EXPECT_DOUBLE_EQ(truth.front().T_w_b.t.x(), 0.878895);
  EXPECT_NEAR(truth.front().T_w_b.q.w(), 0.069433, 1e-6);
  EXPECT_NEAR(truth.front().T_w_b.q.x(), -0.824237, 1e-6);
  EXPECT_DOUBLE_EQ(truth.front().v_w.z(), -0.00231615);
  EXPECT_DOUBLE_EQ(truth.front().bg.x(), -0.00224703);
  EXPECT_DOUBLE_EQ(truth.front().ba.z(), 0.0309774);
  EXPECT_EQ(dataset.groundTruthTimeRange()->end, kLastGroundTruthNs);
  const Trajectory trajectory = dataset.groundTruthTrajectory();
  ASSERT_EQ(trajectory.size(), 2895u);
  EXPECT_DOUBLE_EQ(trajectory[1].T_w_x.t.y(), 2.18348);

  const auto nearest =
      dataset.groundTruthNearest(kSecondFrameNs + 20 * kNsPerMillisecond, 30 * kNsPerMillisecond);
  ASSERT_TRUE(nearest.has_value());
  EXPECT_EQ(nearest->t_ns, kSecondFrameNs);
  EXPECT_EQ(
      dataset.groundTruthNearest(kSecondFrameNs + 30 * kNsPerMillisecond, 30 * kNsPerMillisecond)
          ->t_ns,
      1403715273362142976);  // the third row is nearer
  EXPECT_FALSE(
      dataset.groundTruthNearest(kSecondFrameNs + 20 * kNsPerMillisecond, 10 * kNsPerMillisecond));
  EXPECT_EQ(dataset.groundTruthNearest(0, std::numeric_limits<TimeNs>::max())->t_ns, kFirstFrameNs);

  const cv::Mat image = loadImage(stereo[10].cam1, *dataset.cam1Calibration());
  EXPECT_EQ(image.cols, 752);
  EXPECT_EQ(image.rows, 480);
  EXPECT_EQ(image.type(), CV_8UC1);
}

TEST(EurocDatasetTest, OpensTheMav0FolderItself) {
  SUPERDYNA_REQUIRE_SHARED(mav0, std::string(kSequence) + "/mav0");
  const EurocDataset dataset = EurocDataset::open(mav0);
  EXPECT_EQ(dataset.root(), mav0);
  EXPECT_EQ(dataset.stereoFrames().size(), 95u);
}

TEST(EurocDatasetTest, ReadsASmallCopyAndAMonoCopy) {
  SUPERDYNA_REQUIRE_SHARED(sequence, kSequence);
  ScratchDir dir("euroc_small");
  makeSmallCopy(sequence, dir);
  const EurocDataset stereo = EurocDataset::open(dir.path());
  EXPECT_EQ(stereo.stereoFrames().size(), 3u);
  EXPECT_TRUE(stereo.warnings().empty());
  EXPECT_EQ(stereo.imu().size(), 100u);
  EXPECT_EQ(stereo.groundTruth().size(), 10u);

  fs::remove_all(dir / "mav0/cam1");
  fs::remove_all(dir / "mav0/state_groundtruth_estimate0");
  const EurocDataset mono = EurocDataset::open(dir / "mav0");
  EXPECT_FALSE(mono.isStereo());
  EXPECT_FALSE(mono.cam1Calibration().has_value());
  EXPECT_FALSE(mono.cam1TimeRange().has_value());
  EXPECT_TRUE(mono.stereoFrames().empty());
  EXPECT_EQ(mono.monoFrames().size(), 3u);
  EXPECT_EQ(mono.monoFramesWithImuCoverage().size(), 3u);
  EXPECT_FALSE(mono.hasGroundTruth());
  EXPECT_FALSE(mono.groundTruthTimeRange().has_value());
  EXPECT_FALSE(mono.groundTruthNearest(kFirstFrameNs, kNsPerSecond).has_value());

  fs::remove_all(dir / "mav0/imu0");
  const EurocDataset vision_only = EurocDataset::open(dir / "mav0");
  EXPECT_FALSE(vision_only.hasImu());
  EXPECT_TRUE(vision_only.imuBetween(kFirstFrameNs, kLastFrameNs).empty());
  EXPECT_TRUE(vision_only.monoFramesWithImuCoverage().empty());
}

TEST(EurocDatasetTest, WarnsAboutUnpairedFramesAndImuGaps) {
  SUPERDYNA_REQUIRE_SHARED(sequence, kSequence);
  ScratchDir dir("euroc_warnings");
  makeSmallCopy(sequence, dir);
  editLine(dir / "mav0/cam1/data.csv", 3, "");  // cam0's second frame loses its partner
  // Drop IMU rows 20..29: a 55 ms gap, 11 nominal periods, ending at what is then line 20.
  for (int i = 0; i < 10; ++i)
    editLine(dir / "mav0/imu0/data.csv", 20, "");
  const EurocDataset dataset = EurocDataset::open(dir.path());
  EXPECT_EQ(dataset.stereoFrames().size(), 2u);
  EXPECT_EQ(dataset.monoFrames().size(), 3u);
  EXPECT_EQ(dataset.stereoFrames()[1].t_ns, 1403715273362142976);
  EXPECT_EQ(dataset.imu().size(), 90u);
  ASSERT_EQ(dataset.warnings().size(), 2u);
  EXPECT_TRUE(anyContains(dataset.warnings(), "cam0/data.csv: 1 frame(s) have no cam1 frame"));
  EXPECT_TRUE(anyContains(dataset.warnings(), "first at line 3, t_ns 1403715273312143104"));
  EXPECT_TRUE(
      anyContains(dataset.warnings(), "imu0/data.csv: 1 gap(s) longer than 5 nominal periods"));
  EXPECT_TRUE(anyContains(dataset.warnings(), "55.0 ms, ends at line 20"));
}

TEST(EurocDatasetTest, SkipsNonFiniteImuRowsAndReportsDroppedFrames) {
  SUPERDYNA_REQUIRE_SHARED(sequence, kSequence);
  ScratchDir dir("euroc_faults");
  makeSmallCopy(sequence, dir);
  editLine(dir / "mav0/imu0/data.csv", 5, "1403715273282142976,0.1,nan,0.1,9.0,0.1,-3.7");
  editLine(dir / "mav0/imu0/data.csv", 6, "1403715273287142912,inf,0.1,0.1,9.0,0.1,-3.7");
  editLine(dir / "mav0/imu0/data.csv", 9, "1403715273302142976,NaN,NaN,NaN,NaN,NaN,NaN");
  // cam0's second frame dropped by the driver (row gone; cam1 keeps it, unpaired).
  editLine(dir / "mav0/cam0/data.csv", 3, "");
  const EurocDataset dataset = EurocDataset::open(dir.path());
  EXPECT_EQ(dataset.imu().size(), 97u);
  for (const sensors::ImuSample& sample : dataset.imu()) {
    EXPECT_TRUE(sample.gyro.allFinite() && sample.accel.allFinite());
  }
  EXPECT_TRUE(anyContains(dataset.warnings(),
                          "imu0/data.csv: 3 row(s) with nan or inf values skipped (lines 5-6, 9)"));
  EXPECT_TRUE(anyContains(dataset.warnings(),
                          "cam0/data.csv: about 1 dropped frame(s) in 1 time "
                          "step(s) longer than 1.5 frame periods of 20 Hz"));
  EXPECT_TRUE(anyContains(dataset.warnings(), "the largest, 100.0 ms, ends at line 3"));
}

TEST(EurocDatasetTest, PutsRowsBackInTimeOrderAndSkipsRepeatedTimestampsReportingTheirLines) {
  SUPERDYNA_REQUIRE_SHARED(sequence, kSequence);
  ScratchDir dir("euroc_order");
  makeSmallCopy(sequence, dir);
  const fs::path mav0 = dir.path() / "mav0";
  const std::vector<std::string> imu = lines(readFile(mav0 / "imu0/data.csv"));
  const std::vector<std::string> cam0 = lines(readFile(mav0 / "cam0/data.csv"));
  const std::vector<std::string> cam1 = lines(readFile(mav0 / "cam1/data.csv"));
  const EurocDataset clean = EurocDataset::open(dir.path());
  // IMU rows 5 and 6 swapped, row 10 written twice; cam0's rows 3 and 4 swapped; cam1's
  // row 3 written twice (lines are 1-based, line 1 the header).
  editLine(mav0 / "imu0/data.csv", 5, imu[5]);
  editLine(mav0 / "imu0/data.csv", 6, imu[4]);
  editLine(mav0 / "imu0/data.csv", 10, imu[9] + "\n" + imu[9]);
  editLine(mav0 / "cam0/data.csv", 3, cam0[3]);
  editLine(mav0 / "cam0/data.csv", 4, cam0[2]);
  editLine(mav0 / "cam1/data.csv", 3, cam1[2] + "\n" + cam1[2]);
  const EurocDataset dataset = EurocDataset::open(dir.path());
  ASSERT_EQ(dataset.imu().size(), clean.imu().size());
  for (std::size_t k = 0; k < clean.imu().size(); ++k) {
    EXPECT_EQ(dataset.imu()[k].t_ns, clean.imu()[k].t_ns);
    EXPECT_EQ(dataset.imu()[k].gyro, clean.imu()[k].gyro);
  }
  ASSERT_EQ(dataset.stereoFrames().size(), clean.stereoFrames().size());
  for (std::size_t k = 0; k < clean.stereoFrames().size(); ++k) {
    EXPECT_EQ(dataset.stereoFrames()[k].t_ns, clean.stereoFrames()[k].t_ns);
    EXPECT_EQ(dataset.stereoFrames()[k].cam0, clean.stereoFrames()[k].cam0);
  }
  const auto& warnings = dataset.warnings();
  EXPECT_TRUE(anyContains(warnings,
                          "imu0/data.csv: 1 row(s) out of time order put back in order "
                          "(lines 6)"));
  EXPECT_TRUE(anyContains(warnings,
                          "imu0/data.csv: 1 row(s) repeating an earlier row's timestamp "
                          "skipped (lines 11)"));
  EXPECT_TRUE(anyContains(warnings,
                          "cam0/data.csv: 1 row(s) out of time order put back in order "
                          "(lines 4)"));
  EXPECT_TRUE(anyContains(warnings,
                          "cam1/data.csv: 1 row(s) repeating an earlier row's timestamp "
                          "skipped (lines 4)"));
}

TEST(EurocDatasetTest, SkipsSaturatedImuRowsWhenTheSensorYamlGivesTheRanges) {
  SUPERDYNA_REQUIRE_SHARED(sequence, kSequence);
  ScratchDir dir("euroc_saturated");
  makeSmallCopy(sequence, dir);
  const fs::path mav0 = dir.path() / "mav0";
  editLine(mav0 / "imu0/data.csv", 5, "1403715273277143040,0.1,-8.7266,0.1,9.0,0.1,-3.7");
  editLine(mav0 / "imu0/data.csv", 7, "1403715273287142912,0.1,0.1,0.1,9.0,-39.2,-3.7");
  // Without ranges nothing is known to be clipped.
  EXPECT_EQ(EurocDataset::open(dir.path()).imu().size(), 100u);
  std::ofstream(mav0 / "imu0/sensor.yaml", std::ios::app)
      << "gyroscope_range: 8.7266\naccelerometer_range: 39.2\n";
  const EurocDataset dataset = EurocDataset::open(dir.path());
  EXPECT_EQ(dataset.imuCalibration()->gyroscope_range, 8.7266);
  EXPECT_EQ(dataset.imu().size(), 98u);
  EXPECT_TRUE(anyContains(dataset.warnings(),
                          "imu0/data.csv: 2 row(s) at the sensor's range "
                          "(saturated: |gyro| >= 8.7266 rad/s or |accel| >= "
                          "39.2 m/s^2, sensor.yaml) skipped (lines 5, 7)"));
}

TEST(EurocDatasetTest, RejectsCorruptedCopiesNamingFileLineAndField) {
  SUPERDYNA_REQUIRE_SHARED(sequence, kSequence);
  struct Case {
    std::string name;
    std::function<void(const fs::path& mav0)> corrupt;
    std::vector<std::string> fragments;
  };
  const std::vector<Case> cases = {
      {"truncated imu row",
       [](const fs::path& mav0) {
         editLine(mav0 / "imu0/data.csv", 7, "1403715273292142848,-0.0013,0.0195,0.0782");
       },
       {"imu0/data.csv:7", "expected 7 fields, found 4"}},
      {"word in imu",
       [](const fs::path& mav0) {
         editLine(mav0 / "imu0/data.csv", 5, "1403715273282142976,0.1,nann,0.1,9.0,0.1,-3.7");
       },
       {"imu0/data.csv:5 [gyro_y]", "'nann' is not a number"}},
      {"missing png",
       [](const fs::path& mav0) { fs::remove(mav0 / "cam0/data/1403715273312143104.png"); },
       {"cam0/data.csv:3 [filename]", "cam0/data/1403715273312143104.png does not exist"}},
      {"missing png of a paired cam1 frame",
       [](const fs::path& mav0) { fs::remove(mav0 / "cam1/data/1403715273362142976.png"); },
       {"cam1/data.csv:4 [filename]", "1403715273362142976.png does not exist"}},
      {"file name over the system's length limit (threw std::filesystem_error before)",
       [](const fs::path& mav0) {
         editLine(mav0 / "cam0/data.csv", 3, "1403715273312143104," + std::string(300, 'x'));
       },
       {"cam0/data.csv:3 [filename]", "cannot be looked up"}},
      {"camera row without file name",
       [](const fs::path& mav0) { editLine(mav0 / "cam0/data.csv", 2, "1403715273262142976"); },
       {"cam0/data.csv:2", "expected 2 fields, found 1"}},
      {"missing intrinsics",
       [](const fs::path& mav0) {
         std::vector<std::string> yaml = lines(readFile(mav0 / "cam0/sensor.yaml"));
         std::erase_if(yaml,
                       [](const std::string& line) { return line.starts_with("intrinsics:"); });
         writeFile(mav0 / "cam0/sensor.yaml", joined(yaml));
       },
       {"cam0/sensor.yaml [intrinsics]", "missing field"}},
      {"missing camera calibration file",
       [](const fs::path& mav0) { fs::remove(mav0 / "cam1/sensor.yaml"); },
       {"cam1/sensor.yaml", "does not exist"}},
      {"missing imu csv",
       [](const fs::path& mav0) { fs::remove(mav0 / "imu0/data.csv"); },
       {"imu0/data.csv", "does not exist"}},
      {"bad ground-truth quaternion",
       [](const fs::path& mav0) {
         const fs::path csv = mav0 / "state_groundtruth_estimate0/data.csv";
         // q_w 0.0694202 -> 0.5: norm 1.12.
         editLine(csv, 4,
                  "1403715273362142976,0.879043,2.18353,0.948278,0.5,-0.824264,-0.106935,"
                  "-0.551665,0.000681035,0.000669648,-0.000582798,-0.00224701,0.0215352,"
                  "0.0770298,-0.0179845,0.0660077,0.0309696");
       },
       {"state_groundtruth_estimate0/data.csv:4 [quaternion]", "quaternion norm"}},
      {"truncated ground-truth row",
       [](const fs::path& mav0) {
         const fs::path csv = mav0 / "state_groundtruth_estimate0/data.csv";
         editLine(csv, 3, "1403715273312143104,0.878973,2.18348,0.948329,0.0694375,-0.824253");
       },
       {"state_groundtruth_estimate0/data.csv:3", "expected 17 fields, found 6"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    ScratchDir dir("euroc_corrupt");
    makeSmallCopy(sequence, dir);
    c.corrupt(dir / "mav0");
    std::vector<std::string> fragments = c.fragments;
    test::expectError([&] { EurocDataset::open(dir.path()); }, {fragments[0], fragments[1]});
  }
}

TEST(EurocDatasetTest, ReadsPoseOnlyGroundTruth) {
  SUPERDYNA_REQUIRE_SHARED(sequence, kSequence);
  ScratchDir dir("euroc_pose_only");
  makeSmallCopy(sequence, dir);
  writeFile(dir / "mav0/state_groundtruth_estimate0/data.csv",
            "#timestamp,p_x,p_y,p_z,q_w,q_x,q_y,q_z\n"
            "1403715273262142976,1.0,2.0,3.0,1.0,0.0,0.0,0.0\n"
            "1403715273312143104,1.5,2.0,3.0,0.0,0.0,0.0,1.0\n");
  const EurocDataset dataset = EurocDataset::open(dir.path());
  ASSERT_EQ(dataset.groundTruth().size(), 2u);
  EXPECT_FALSE(dataset.groundTruthHasVelocityAndBiases());
  EXPECT_TRUE(dataset.groundTruth()[1].v_w.isZero(0.0));
  EXPECT_TRUE(dataset.groundTruth()[1].ba.isZero(0.0));
  EXPECT_DOUBLE_EQ(dataset.groundTruth()[1].T_w_b.t.x(), 1.5);
  EXPECT_NEAR(std::abs(dataset.groundTruth()[1].T_w_b.q.z()), 1.0, 1e-12);
}

TEST(EurocDatasetTest, LoadImageRejectsWrongSizeAndGarbage) {
  SUPERDYNA_REQUIRE_SHARED(sequence, kSequence);
  ScratchDir dir("euroc_images");
  makeSmallCopy(sequence, dir);
  const EurocDataset dataset = EurocDataset::open(dir.path());
  const StereoFrameRef& frame = dataset.stereoFrames()[1];
  EXPECT_EQ(loadImage(frame.cam0, dataset.cam0Calibration()).size(), cv::Size(752, 480));

  // Opening checks that images exist; their size and content are checked when loaded.
  ASSERT_TRUE(cv::imwrite(frame.cam0.string(), cv::Mat(240, 376, CV_8UC1, cv::Scalar(128))));
  writeFile(frame.cam1, "not a png at all, just bytes");
  const EurocDataset reopened = EurocDataset::open(dir.path());
  test::expectError([&] { loadImage(frame.cam0, reopened.cam0Calibration()); },
                    {"cam0/data/1403715273312143104.png", "is 376x240, expected 752x480"});
  test::expectError([&] { loadImage(frame.cam1, *reopened.cam1Calibration()); },
                    {"cam1/data/1403715273312143104.png", "cannot decode"});
}

TEST(EurocDatasetTest, RejectsFoldersThatAreNotEurocSequences) {
  ScratchDir dir("euroc_not");
  test::expectError([&] { EurocDataset::open(dir / "absent"); }, {"absent", "does not exist"});
  fs::create_directories(dir / "mav0/imu0");
  test::expectError([&] { EurocDataset::open(dir.path()); }, {"not a EuRoC sequence"});
  fs::create_directories(dir / "mav0/cam0");
  test::expectError([&] { EurocDataset::open(dir.path()); },
                    {"cam0/sensor.yaml", "does not exist"});
}

}  // namespace
}  // namespace superdyna::io

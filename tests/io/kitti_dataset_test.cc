#include "superdyna/io/kitti_dataset.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <functional>
#include <opencv2/imgcodecs.hpp>

#include "superdyna/core/error.h"
#include "support/test_support.h"

namespace superdyna::io {
namespace {

namespace fs = std::filesystem;
using test::readFile;
using test::ScratchDir;
using test::writeFile;

constexpr const char* kSnippet = "data/kitti/snippet_1";

/// Labelled calib.txt as the KITTI odometry benchmark ships it (values of the grayscale pair
/// from the snippet; P2/P3 chosen so that the colour baseline is (42 + 329) / 700 = 0.53 m).
std::string labelledCalib() {
  return "P0: 7.070912e+02 0 6.018873e+02 0 0 7.070912e+02 1.831104e+02 0 0 0 1 0\n"
         "P1: 7.070912e+02 0 6.018873e+02 -3.798145e+02 0 7.070912e+02 1.831104e+02 0 0 0 1 0\n"
         "P2: 700 0 600 42 0 700 180 0 0 0 1 0\n"
         "P3: 700 0 600 -329 0 700 180 0 0 0 1 0\n"
         "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n";
}

/// A sequence folder with `count` images of the snippet in each of `folders`.
void makeSequence(const fs::path& snippet, const fs::path& dir,
                  std::initializer_list<const char*> folders, int count = 3) {
  for (const char* folder : folders) {
    fs::create_directories(dir / folder);
    for (int i = 0; i < count; ++i) {
      const std::string name = fmt::format("{:06d}.png", i);
      writeFile(dir / folder / name, readFile(snippet / "image_l" / name));
    }
  }
  writeFile(dir / "calib.txt", labelledCalib());
}

TEST(KittiDatasetTest, ReadsTheRealSnippet) {
  SUPERDYNA_REQUIRE_SHARED(snippet, kSnippet);
  const KittiDataset dataset = KittiDataset::open(snippet);
  ASSERT_EQ(dataset.size(), 51u);
  EXPECT_FALSE(dataset.isStereo());  // image_l only
  EXPECT_EQ(dataset.monoFrames().front().path, snippet / "image_l/000000.png");
  EXPECT_EQ(dataset.monoFrames().back().path, snippet / "image_l/000050.png");

  // No times.txt: 10 Hz from zero, with a warning.
  EXPECT_FALSE(dataset.hasTimesFile());
  EXPECT_EQ(dataset.monoFrames()[10].t_ns, kNsPerSecond);
  EXPECT_EQ(dataset.timeRange().end, 5 * kNsPerSecond);
  ASSERT_EQ(dataset.warnings().size(), 1u);
  EXPECT_NE(dataset.warnings()[0].find("times.txt not found"), std::string::npos);

  // The snippet's calib.txt has unlabelled rows: P0 then P1.
  const sensors::CameraCalibration& left = dataset.leftCalibration();
  EXPECT_EQ(left.name, "image_l");
  EXPECT_DOUBLE_EQ(left.fx, 707.0912);
  EXPECT_DOUBLE_EQ(left.fy, 707.0912);
  EXPECT_DOUBLE_EQ(left.cx, 601.8873);
  EXPECT_DOUBLE_EQ(left.cy, 183.1104);
  EXPECT_EQ(left.width, 1226);
  EXPECT_EQ(left.height, 370);
  EXPECT_DOUBLE_EQ(left.rate_hz, 10.0);
  EXPECT_EQ(left.distortion_model, DistortionModel::kNone);
  EXPECT_TRUE(left.T_b_c.matrix().isIdentity(0.0));
  ASSERT_TRUE(dataset.baseline().has_value());
  EXPECT_NEAR(*dataset.baseline(), 379.8145 / 707.0912, 1e-12);
  EXPECT_NEAR(*dataset.baseline(), 0.5372, 1e-4);
  EXPECT_NEAR(dataset.rightCalibration()->T_b_c.t.norm(), *dataset.baseline(), 1e-12);

  // poses.txt: ground truth of the left camera, one pose per frame, at the frame times.
  ASSERT_TRUE(dataset.hasGroundTruth());
  ASSERT_EQ(dataset.groundTruth().size(), 51u);
  EXPECT_EQ(dataset.groundTruth()[1].t_ns, 100 * kNsPerMillisecond);
  EXPECT_DOUBLE_EQ(dataset.groundTruth()[1].T_w_x.t.z(), 1.198998);
  EXPECT_DOUBLE_EQ(dataset.groundTruth()[1].T_w_x.t.x(), -1.401751e-02);

  const cv::Mat image = loadImage(dataset.monoFrames()[25].path, left);
  EXPECT_EQ(image.size(), cv::Size(1226, 370));
  EXPECT_EQ(image.type(), CV_8UC1);
}

TEST(KittiDatasetTest, ReadsLabelledCalibStereoAndTimes) {
  SUPERDYNA_REQUIRE_SHARED(snippet, kSnippet);
  ScratchDir dir("kitti_labelled");
  makeSequence(snippet, dir.path(), {"image_0", "image_1"});
  writeFile(dir / "times.txt", "0.000000e+00\n1.037359e-01\n2.073449e-01\n");
  const KittiDataset dataset = KittiDataset::open(dir.path());
  ASSERT_TRUE(dataset.isStereo());
  ASSERT_EQ(dataset.stereoFrames().size(), 3u);
  EXPECT_EQ(dataset.stereoFrames()[2].cam1, dir / "image_1/000002.png");
  EXPECT_TRUE(dataset.hasTimesFile());
  EXPECT_TRUE(dataset.warnings().empty());
  EXPECT_EQ(dataset.stereoFrames()[1].t_ns, 103'735'900);
  EXPECT_NEAR(dataset.leftCalibration().rate_hz, 2.0 / 0.2073449, 1e-9);
  EXPECT_DOUBLE_EQ(dataset.leftCalibration().cy, 183.1104);
  EXPECT_NEAR(*dataset.baseline(), 0.5372, 1e-4);
  EXPECT_FALSE(dataset.hasGroundTruth());

  // Poses given explicitly take the frame times of times.txt.
  const fs::path poses = dir / "gt.txt";
  writeFile(poses, "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0.1 0 1 0 0 0 0 1 1\n1 0 0 0 0 1 0 0 0 0 1 2\n");
  const KittiDataset with_poses = KittiDataset::open(dir.path(), poses);
  ASSERT_EQ(with_poses.groundTruth().size(), 3u);
  EXPECT_EQ(with_poses.groundTruth()[2].t_ns, 207'344'900);
  EXPECT_DOUBLE_EQ(with_poses.groundTruth()[1].T_w_x.t.z(), 1.0);
}

TEST(KittiDatasetTest, UsesP2AndP3ForTheColourPair) {
  SUPERDYNA_REQUIRE_SHARED(snippet, kSnippet);
  ScratchDir dir("kitti_colour");
  makeSequence(snippet, dir.path(), {"image_2", "image_3"});
  const KittiDataset dataset = KittiDataset::open(dir.path());
  EXPECT_EQ(dataset.leftCalibration().name, "image_2");
  EXPECT_DOUBLE_EQ(dataset.leftCalibration().fx, 700.0);
  EXPECT_DOUBLE_EQ(dataset.leftCalibration().cy, 180.0);
  EXPECT_NEAR(*dataset.baseline(), 0.53, 1e-12);
  EXPECT_NEAR(dataset.rightCalibration()->T_b_c.t.x(), 0.53, 1e-12);
}

TEST(KittiDatasetTest, RejectsBadSequencesWithClearErrors) {
  SUPERDYNA_REQUIRE_SHARED(snippet, kSnippet);
  const std::string p0 = "707 0 601 0 0 707 183 0 0 0 1 0\n";
  struct Case {
    std::string name;
    std::function<void(const fs::path&)> corrupt;
    std::vector<std::string> fragments;
  };
  const std::vector<Case> cases = {
      {"times count",
       [](const fs::path& d) { writeFile(d / "times.txt", "0.0\n0.1\n"); },
       {"times.txt", "2 timestamps but 3 images"}},
      {"unsorted times",
       [](const fs::path& d) { writeFile(d / "times.txt", "0.0\n0.2\n0.1\n"); },
       {"times.txt:3", "earlier than the previous"}},
      {"short calib row",
       [&](const fs::path& d) {
         writeFile(d / "calib.txt", p0 + "707 0 601 -379 0 707 183 0 0 0 1\n");
       },
       {"calib.txt:2", "expected 12 fields, found 11"}},
      {"bad number",
       [&](const fs::path& d) {
         writeFile(d / "calib.txt", "P0: 707 0 601 0 0 x 183 0 0 0 1 0\n");
       },
       {"calib.txt:1 [m11]", "'x' is not a number"}},
      {"no P0",
       [](const fs::path& d) {
         writeFile(d / "calib.txt", "P1: 707 0 601 -379 0 707 183 0 0 0 1 0\n");
       },
       {"calib.txt [P0]", "missing projection matrix"}},
      {"mixed labels",
       [&](const fs::path& d) { writeFile(d / "calib.txt", "P0: " + p0 + p0); },
       {"calib.txt:2", "mixes labelled"}},
      {"not rectified",
       [](const fs::path& d) { writeFile(d / "calib.txt", "0 0 601 0 0 707 183 0 0 0 1 0\n"); },
       {"calib.txt [P0]", "not a rectified projection matrix"}},
      {"missing calib",
       [](const fs::path& d) { fs::remove(d / "calib.txt"); },
       {"calib.txt", "does not exist"}},
      {"poses count",
       [](const fs::path& d) {
         writeFile(d / "poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 1\n");
       },
       {"poses.txt", "2 poses but 3 images"}},
      {"bad pose",
       [](const fs::path& d) { writeFile(d / "poses.txt", "1 0 0 0 0 1 0 0 0 0 2 0\n"); },
       {"poses.txt:1", "not orthonormal"}},
      {"right images differ",
       [](const fs::path& d) { fs::remove(d / "image_r/000001.png"); },
       {"image_r", "do not match", "000001.png"}},
      {"unreadable first image",
       [](const fs::path& d) { writeFile(d / "image_l/000000.png", "garbage bytes"); },
       {"image_l/000000.png", "cannot decode"}},
      {"no images",
       [](const fs::path& d) { fs::remove_all(d / "image_l"); },
       {"not a KITTI sequence"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    ScratchDir dir("kitti_bad");
    makeSequence(snippet, dir.path(), {"image_l", "image_r"});
    c.corrupt(dir.path());
    std::vector<std::string> fragments = c.fragments;
    fragments.resize(3);
    test::expectError([&] { KittiDataset::open(dir.path()); },
                      {fragments[0], fragments[1], fragments[2]});
  }
}

TEST(KittiDatasetTest, LoadImageChecksEveryImageAgainstTheFirst) {
  SUPERDYNA_REQUIRE_SHARED(snippet, kSnippet);
  ScratchDir dir("kitti_sizes");
  makeSequence(snippet, dir.path(), {"image_l"});
  ASSERT_TRUE(
      cv::imwrite((dir / "image_l/000002.png").string(), cv::Mat(50, 100, CV_8UC1, cv::Scalar(7))));
  const KittiDataset dataset = KittiDataset::open(dir.path());
  EXPECT_EQ(loadImage(dataset.monoFrames()[1].path, dataset.leftCalibration()).cols, 1226);
  test::expectError([&] { loadImage(dataset.monoFrames()[2].path, dataset.leftCalibration()); },
                    {"image_l/000002.png", "is 100x50, expected 1226x370"});
}

}  // namespace
}  // namespace superdyna::io

#include "superdyna/io/dataset_source.h"

#include <gtest/gtest.h>

#include "support/test_support.h"

namespace superdyna::io {
namespace {

namespace fs = std::filesystem;

constexpr const char* kEuroc = "data/euroc/V1_01_easy_micro";
constexpr const char* kKitti = "data/kitti/snippet_1";

TEST(DatasetSourceTest, EurocStereoInertialServesEveryFrameWithBracketingImu) {
  SUPERDYNA_REQUIRE_SHARED(path, kEuroc);
  const auto source = openDataset(DatasetKind::kEuroc, path, {});
  ASSERT_EQ(source->size(), 95u);
  ASSERT_TRUE(source->camera1());
  ASSERT_TRUE(source->imu());
  TimeNs previous = 0;
  std::size_t frames = 0;
  while (const auto bundle = source->next()) {
    EXPECT_EQ(bundle->index, frames);
    EXPECT_EQ(bundle->image0.size(), cv::Size(752, 480));
    EXPECT_EQ(bundle->image1.size(), cv::Size(752, 480));
    ASSERT_FALSE(bundle->imu.empty());
    // The samples bracket [previous frame, this frame] for interpolation at both ends.
    EXPECT_LE(bundle->imu.front().t_ns, frames == 0 ? bundle->t_ns : previous);
    EXPECT_GE(bundle->imu.back().t_ns, bundle->t_ns);
    if (frames > 0) {
      EXPECT_GE(bundle->imu.size(), 11u);  // 50 ms at 200 Hz, plus the bracketing samples
      EXPECT_LE(bundle->imu.size(), 12u);
    }
    EXPECT_TRUE(bundle->T_w_b_gt.has_value());
    previous = bundle->t_ns;
    ++frames;
  }
  EXPECT_EQ(frames, 95u);
  EXPECT_EQ(previous, 1403715277962142976LL);
  EXPECT_FALSE(source->next());
  const Trajectory gt = source->groundTruth();
  EXPECT_EQ(gt.size(), 95u);  // the ground truth of the served range only
}

TEST(DatasetSourceTest, EurocMonoWithSkipAndLimit) {
  SUPERDYNA_REQUIRE_SHARED(path, kEuroc);
  DatasetSourceOptions options;
  options.stereo = false;
  options.first_frame = 10;
  options.max_frames = 20;
  const auto source = openDataset(DatasetKind::kEuroc, path, options);
  EXPECT_EQ(source->size(), 20u);
  EXPECT_FALSE(source->camera1());
  const auto first = source->next();
  ASSERT_TRUE(first);
  EXPECT_TRUE(first->image1.empty());
  EXPECT_EQ(first->t_ns, 1403715273762142976LL);  // the 11th frame
  options.first_frame = 95;
  test::expectError<OptionError>([&] { openDataset(DatasetKind::kEuroc, path, options); },
                                 {"only 95 usable frames"});
}

TEST(DatasetSourceTest, KittiMonoServesGroundTruthAndRefusesImuAndStereo) {
  SUPERDYNA_REQUIRE_SHARED(path, kKitti);
  DatasetSourceOptions options;
  options.stereo = false;
  options.inertial = false;
  const auto source = openDataset(DatasetKind::kKitti, path, options);
  EXPECT_EQ(source->size(), 51u);
  EXPECT_FALSE(source->imu());
  const auto first = source->next();
  ASSERT_TRUE(first);
  EXPECT_EQ(first->image0.size(), cv::Size(1226, 370));
  EXPECT_TRUE(first->imu.empty());
  EXPECT_TRUE(first->T_w_b_gt.has_value());
  EXPECT_EQ(source->groundTruth().size(), 51u);
  options.inertial = true;
  test::expectError([&] { openDataset(DatasetKind::kKitti, path, options); }, {"has no IMU"});
  options.inertial = false;
  options.stereo = true;
  test::expectError([&] { openDataset(DatasetKind::kKitti, path, options); }, {"no right images"});
}

TEST(DatasetSourceTest, ParsesKindNames) {
  EXPECT_EQ(parseDatasetKind("euroc"), DatasetKind::kEuroc);
  EXPECT_EQ(parseDatasetKind("kitti"), DatasetKind::kKitti);
  EXPECT_THROW(parseDatasetKind("tum"), OptionError);
}

}  // namespace
}  // namespace superdyna::io

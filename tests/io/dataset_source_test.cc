#include "superdyna/io/dataset_source.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

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

/// The shared EuRoC excerpt (linked, not copied) plus instance masks for the first three stereo
/// frames of both cameras: a vehicle (id 1) rectangle and a pedestrian (id 2) one; with
/// `stray_id` > 0 the third cam0 mask also holds that id, which instances.csv does not list.
fs::path eurocWithMasks(const fs::path& shared, const test::ScratchDir& dir, int stray_id = 0) {
  const fs::path mav0 = dir / "seq" / "mav0";
  fs::create_directories(mav0);
  for (const char* stream : {"imu0", "state_groundtruth_estimate0"})
    fs::create_directory_symlink(shared / "mav0" / stream, mav0 / stream);
  for (const char* camera : {"cam0", "cam1"}) {
    fs::create_directories(mav0 / camera / "mask");
    for (const char* entry : {"sensor.yaml", "data.csv"})
      fs::create_symlink(shared / "mav0" / camera / entry, mav0 / camera / entry);
    fs::create_directory_symlink(shared / "mav0" / camera / "data", mav0 / camera / "data");
  }
  test::writeFile(mav0 / "instances.csv",
                  "# id,class,moving,t_begin_ns,t_end_ns\n1,vehicle,1,0,0\n2,pedestrian,0,0,0\n");
  const EurocDataset dataset = EurocDataset::open(dir / "seq");
  for (std::size_t k = 0; k < 3; ++k) {
    const StereoFrameRef& frame = dataset.stereoFrames()[k];
    for (const fs::path& image : {frame.cam0, frame.cam1}) {
      cv::Mat mask(480, 752, CV_16UC1, cv::Scalar(0));
      mask(cv::Rect(100, 50, 200, 100)).setTo(1);
      mask(cv::Rect(400, 300, 40, 120)).setTo(2);
      if (stray_id > 0 && k == 2 && image == frame.cam0) mask.at<std::uint16_t>(5, 7) = stray_id;
      const fs::path file = image.parent_path().parent_path() / "mask" / image.filename();
      EXPECT_TRUE(cv::imwrite(file.string(), mask)) << file;
    }
  }
  return dir / "seq";
}

TEST(DatasetSourceTest, EurocServesInstanceMasksWhenAsked) {
  SUPERDYNA_REQUIRE_SHARED(shared, kEuroc);
  const test::ScratchDir dir("dataset_source_masks");
  const fs::path path = eurocWithMasks(shared, dir);
  EXPECT_TRUE(EurocDataset::open(path).hasInstanceMasks());
  EXPECT_FALSE(EurocDataset::open(shared).hasInstanceMasks());

  DatasetSourceOptions options;
  options.max_frames = 3;
  EXPECT_FALSE(openDataset(DatasetKind::kEuroc, path, options)->next()->masks);
  options.instance_masks = true;
  const auto source = openDataset(DatasetKind::kEuroc, path, options);
  std::size_t frames = 0;
  while (const auto bundle = source->next()) {
    ASSERT_TRUE(bundle->masks);
    const sensors::InstanceMasks& masks = *bundle->masks;
    ASSERT_EQ(masks.cam0.type(), CV_16UC1);
    ASSERT_EQ(masks.cam1.size(), cv::Size(752, 480));
    EXPECT_EQ(masks.cam0.at<std::uint16_t>(60, 110), 1);
    EXPECT_EQ(masks.cam1.at<std::uint16_t>(350, 420), 2);
    EXPECT_EQ(masks.cam0.at<std::uint16_t>(10, 10), 0);
    EXPECT_EQ(masks.classOf(1), sensors::kInstanceClassVehicle);
    EXPECT_EQ(masks.classOf(2), sensors::kInstanceClassPedestrian);
    EXPECT_EQ(masks.classOf(0), sensors::kInstanceClassBackground);
    ++frames;
  }
  EXPECT_EQ(frames, 3u);

  test::expectError([&] { openDataset(DatasetKind::kEuroc, shared, options); },
                    {"instances.csv", "instance masks requested"});
}

TEST(DatasetSourceTest, EurocMaskProblemsNameTheFile) {
  SUPERDYNA_REQUIRE_SHARED(shared, kEuroc);
  const test::ScratchDir dir("dataset_source_bad_masks");
  const fs::path path = eurocWithMasks(shared, dir, 7);
  DatasetSourceOptions options;
  options.instance_masks = true;
  options.max_frames = 3;
  const auto source = openDataset(DatasetKind::kEuroc, path, options);
  ASSERT_TRUE(source->next());
  ASSERT_TRUE(source->next());
  test::expectError([&] { source->next(); }, {"mask", ".png", "instance 7", "instances.csv"});
  options.first_frame = 3;  // no mask was written for the 4th frame
  test::expectError([&] { openDataset(DatasetKind::kEuroc, path, options)->next(); },
                    {"mask file does not exist"});

  test::writeFile(path / "mav0" / "instances.csv", "1,truck,1,0,0\n");
  test::expectError([&] { EurocDataset::open(path); }, {"instances.csv", "unknown class 'truck'"});
}

/// A damaged file that OpenCV's imread hands to GDCM's DICOM reader, which asserts (abort) on it:
/// found by fuzzing instance masks (fuzz/instance_mask_fuzzer.cc).
const std::string kDicomLikeBytes(
    "\x28\x4f\x44\x4c\x5f\x56\x45\x52\x53\x49\x4f\x4e\x5f\x49\x44\xff\xff\xff\xff\xff\xff\xff"
    "\xff\xff\xff\xff\xdf\xff\xff\xff\xff\x65\x5f\x53\x65\x72\x76\x69\x63\x65\xff\xff\xff\xff"
    "\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xf7\xff\xff\xff\xff\xff\xff\xff"
    "\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xdf\xff\xff\xff\xff\xff\xff\xff"
    "\xff\xff\xff\xff\xff\xff\xdf\xff\xff\xff\xff\xff\xff\xff\xff\xff\x00\x00\x00\x00\x44\x3a"
    "\x00\x00\x54\xff\xff\xff\xdf\xff\xff\xff\x00\x00\x00\x44\x54\x45\x44\x00\x00\x44\x49\x43"
    "\x4d\x02\x00\xff\xff\xff\xff\xff\x00\x00\x3a\x00\x00\x00\x00\x44\x54\x45\x44\x00\x00\x00",
    154);

TEST(DatasetSourceTest, EurocMasksThatAreNotPngFilesAreErrorsNotAborts) {
  SUPERDYNA_REQUIRE_SHARED(shared, kEuroc);
  const test::ScratchDir dir("dataset_source_dicom_mask");
  const fs::path path = eurocWithMasks(shared, dir);
  const EurocDataset dataset = EurocDataset::open(path);
  const fs::path image = dataset.stereoFrames().front().cam0;
  const fs::path mask = image.parent_path().parent_path() / "mask" / image.filename();
  test::writeFile(mask, kDicomLikeBytes);
  test::expectError([&] { dataset.loadInstanceMask(image, cv::Size(752, 480)); },
                    {mask.filename().string(), "not a PNG image"});
  test::writeFile(mask, "\x89PNG\r\n\x1a\n truncated");
  test::expectError([&] { dataset.loadInstanceMask(image, cv::Size(752, 480)); },
                    {mask.filename().string(), "cannot decode the PNG image"});
}

TEST(DatasetSourceTest, EurocUnlabelledInstancesAreListedButNeverInTheMasks) {
  SUPERDYNA_REQUIRE_SHARED(shared, kEuroc);
  const test::ScratchDir dir("dataset_source_unlabelled");
  const fs::path path = eurocWithMasks(shared, dir);
  // Instance 3 is a simulated mover of a class the masks do not label.
  test::writeFile(path / "mav0" / "instances.csv",
                  "# id,class,moving,t_begin_ns,t_end_ns\n1,vehicle,1,0,0\n2,pedestrian,0,0,0\n"
                  "3,unlabelled,1,0,0\n");
  const EurocDataset dataset = EurocDataset::open(path);
  EXPECT_EQ(dataset.instanceClasses(),
            (std::map<int, int>{{1, sensors::kInstanceClassVehicle},
                                {2, sensors::kInstanceClassPedestrian}}));
  DatasetSourceOptions options;
  options.instance_masks = true;
  options.max_frames = 3;
  const auto source = openDataset(DatasetKind::kEuroc, path, options);
  const auto bundle = source->next();
  ASSERT_TRUE(bundle && bundle->masks);
  EXPECT_EQ(bundle->masks->classOf(3), sensors::kInstanceClassBackground);
  // A mask holding an unlabelled instance is refused like one holding an unknown id.
  const fs::path third = path / "mav0/cam0/mask" / dataset.stereoFrames()[2].cam0.filename();
  cv::Mat mask = cv::imread(third.string(), cv::IMREAD_UNCHANGED);
  mask.at<std::uint16_t>(5, 7) = 3;
  ASSERT_TRUE(cv::imwrite(third.string(), mask));
  ASSERT_TRUE(source->next());
  test::expectError([&] { source->next(); }, {"instance 3", "instances.csv", "labelled class"});
  test::writeFile(path / "mav0" / "instances.csv", "1,vehicle,1,0,0\n1,unlabelled,1,0,0\n");
  test::expectError([&] { EurocDataset::open(path); },
                    {"instances.csv", "instance 1 listed twice"});
}

TEST(DatasetSourceTest, ParsesKindNames) {
  EXPECT_EQ(parseDatasetKind("euroc"), DatasetKind::kEuroc);
  EXPECT_EQ(parseDatasetKind("kitti"), DatasetKind::kKitti);
  EXPECT_THROW(parseDatasetKind("tum"), OptionError);
}

}  // namespace
}  // namespace superdyna::io

#include "superdyna/tracking/front_end.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <iostream>

#include "superdyna/inference/model_files.h"
#include "superdyna/io/dataset_source.h"
#include "support/test_support.h"

namespace superdyna::tracking {
namespace {

constexpr const char* kEuroc = "data/euroc/V1_01_easy_micro";

TEST(LabelKeypoints, TakesInstanceAndClassFromTheMaskPixel) {
  sensors::InstanceMasks masks;
  masks.cam0 = cv::Mat(40, 60, CV_16UC1, cv::Scalar(0));
  masks.cam0(cv::Rect(10, 5, 10, 10)).setTo(3);  // columns 10..19, rows 5..14
  masks.class_of_instance = {{3, features::kClassPedestrian}};
  std::vector<features::Keypoint> keypoints(4);
  keypoints[0].pixel = {12.0, 7.0};
  keypoints[1].pixel = {19.4, 14.4};   // rounds to (19, 14): inside
  keypoints[2].pixel = {19.6, 7.0};    // rounds to column 20: outside
  keypoints[3].pixel = {-3.0, 100.0};  // clamped to the border pixel (0, 39): background
  labelKeypoints(masks.cam0, masks, keypoints);
  EXPECT_EQ(keypoints[0].instance_id, 3);
  EXPECT_EQ(keypoints[0].class_id, features::kClassPedestrian);
  EXPECT_EQ(keypoints[1].instance_id, 3);
  EXPECT_EQ(keypoints[2].instance_id, 0);
  EXPECT_EQ(keypoints[2].class_id, features::kClassBackground);
  EXPECT_EQ(keypoints[3].instance_id, 0);
}

TEST(LabelKeypoints, MarksKeypointsNearAnotherInstanceAsOnTheBorder) {
  sensors::InstanceMasks masks;
  masks.cam0 = cv::Mat(40, 60, CV_16UC1, cv::Scalar(0));
  masks.cam0(cv::Rect(10, 5, 20, 20)).setTo(3);  // columns 10..29, rows 5..24
  masks.class_of_instance = {{3, features::kClassVehicle}};
  std::vector<features::Keypoint> keypoints(5);
  keypoints[0].pixel = {20.0, 15.0};  // 10 px inside
  keypoints[1].pixel = {12.0, 15.0};  // 2 px inside the left edge
  keypoints[2].pixel = {7.0, 15.0};   // background, 3 px left of the object
  keypoints[3].pixel = {50.0, 30.0};  // background, far from it
  keypoints[4].pixel = {16.0, 15.0};  // 6 px inside, but an octave-6 ORB patch (size 93)
  keypoints[4].size = 93.0f;
  labelKeypoints(masks.cam0, masks, keypoints);
  EXPECT_DOUBLE_EQ(instanceBorderRadiusPx(keypoints[0]), 3.0);
  EXPECT_DOUBLE_EQ(instanceBorderRadiusPx(keypoints[4]), 9.3);
  EXPECT_FALSE(keypoints[0].on_instance_border);
  EXPECT_TRUE(keypoints[1].on_instance_border);
  EXPECT_TRUE(keypoints[2].on_instance_border);
  EXPECT_FALSE(keypoints[3].on_instance_border);
  EXPECT_TRUE(keypoints[4].on_instance_border);
  EXPECT_EQ(keypoints[1].instance_id, 3);
  EXPECT_EQ(keypoints[2].instance_id, 0);
}

/// The first stereo frame of the shared EuRoC excerpt.
sensors::FrameBundle eurocFrame(const std::filesystem::path& path) {
  io::DatasetSourceOptions options;
  options.inertial = false;
  options.max_frames = 1;
  return *io::openDataset(io::DatasetKind::kEuroc, path, options)->next();
}

FrontEnd eurocFrontEnd(const std::filesystem::path& path, const FrontEndOptions& options) {
  io::DatasetSourceOptions source_options;
  source_options.inertial = false;
  const auto source = io::openDataset(io::DatasetKind::kEuroc, path, source_options);
  return FrontEnd(options, source->camera0(), source->camera1());
}

TEST(FrontEnd, ClassWiseStereoNeverPairsAcrossClasses) {
  SUPERDYNA_REQUIRE_SHARED(path, kEuroc);
  sensors::FrameBundle bundle = eurocFrame(path);
  // A "vehicle" over the left half of cam0 only: its keypoints have background partners.
  sensors::InstanceMasks masks;
  masks.cam0 = cv::Mat(bundle.image0.size(), CV_16UC1, cv::Scalar(0));
  masks.cam0.colRange(0, masks.cam0.cols / 2).setTo(1);
  masks.cam1 = cv::Mat(bundle.image1.size(), CV_16UC1, cv::Scalar(0));
  masks.class_of_instance = {{1, features::kClassVehicle}};
  bundle.masks = masks;

  FrontEndOptions options;
  options.stereo.same_class_only = false;
  const Frame blind = eurocFrontEnd(path, options).build(bundle);
  options.stereo.same_class_only = true;
  const Frame class_wise = eurocFrontEnd(path, options).build(bundle);
  ASSERT_EQ(blind.size(), class_wise.size());
  int on_vehicle = 0, stereo_on_vehicle = 0;
  for (std::size_t i = 0; i < class_wise.size(); ++i) {
    const features::Keypoint& k = class_wise.features.keypoints[i];
    EXPECT_EQ(k.class_id, k.pixel.x() < 375.5 ? features::kClassVehicle : 0);
    if (k.class_id != features::kClassVehicle) continue;
    ++on_vehicle;
    if (class_wise.hasStereo(i)) ++stereo_on_vehicle;
  }
  EXPECT_GT(on_vehicle, 300);
  EXPECT_EQ(stereo_on_vehicle, 0);
  EXPECT_EQ(class_wise.cross_class_stereo, 0);
  EXPECT_GT(blind.cross_class_stereo, 100);
  EXPECT_GT(class_wise.numStereo(), 100);
}

TEST(FrontEnd, LeftOnlyMasksLabelStereoPointsFromTheLeftKeypoint) {
  SUPERDYNA_REQUIRE_SHARED(path, kEuroc);
  sensors::FrameBundle bundle = eurocFrame(path);
  // A segmenter run on the left image only: a "vehicle" over its left half, no right mask.
  sensors::InstanceMasks masks;
  masks.cam0 = cv::Mat(bundle.image0.size(), CV_16UC1, cv::Scalar(0));
  masks.cam0.colRange(0, masks.cam0.cols / 2).setTo(1);
  masks.class_of_instance = {{1, features::kClassVehicle}};
  bundle.masks = masks;

  FrontEndOptions options;
  options.stereo.same_class_only = false;
  const Frame blind = eurocFrontEnd(path, options).build(bundle);
  options.stereo.same_class_only = true;
  const Frame left_only = eurocFrontEnd(path, options).build(bundle);
  // Class-wise matching cannot use right labels that do not exist: the stereo search ignores
  // classes and every stereo point keeps its left keypoint's label.
  int stereo_on_vehicle = 0;
  ASSERT_EQ(blind.size(), left_only.size());
  for (std::size_t i = 0; i < left_only.size(); ++i) {
    EXPECT_EQ(left_only.hasStereo(i), blind.hasStereo(i)) << i;
    if (left_only.hasStereo(i) &&
        left_only.features.keypoints[i].class_id == features::kClassVehicle) {
      ++stereo_on_vehicle;
    }
  }
  std::cout << "left-only masks: " << stereo_on_vehicle << " stereo points on the vehicle of "
            << left_only.numStereo() << "\n";
  EXPECT_GT(stereo_on_vehicle, 100);
  EXPECT_EQ(left_only.numStereo(), blind.numStereo());
  EXPECT_EQ(left_only.cross_class_stereo, 0);
}

TEST(FrontEnd, XFeatFramesCarryFloatDescriptorsAndStereoDepth) {
  SUPERDYNA_REQUIRE_SHARED(path, kEuroc);
  SUPERDYNA_REQUIRE_SHARED(model, "models/xfeat.onnx");
  FrontEndOptions options;
  options.features.type = features::FeatureType::kXFeat;
  options.features.model = model.string();
  FrontEnd front_end = eurocFrontEnd(path, options);
  EXPECT_EQ(front_end.pyramid().levels, 1);
  EXPECT_EQ(front_end.extractor().name(), "xfeat");
  const Frame frame = front_end.build(eurocFrame(path));
  EXPECT_EQ(frame.features.descriptor_type, features::DescriptorType::kFloat);
  EXPECT_EQ(frame.size(), 1200u);
  // V1_01 is a room a few metres across: stereo depths between 0.5 and 10 m.
  std::vector<double> depths;
  for (std::size_t i = 0; i < frame.size(); ++i)
    if (frame.hasStereo(i)) depths.push_back(frame.depth_m[i]);
  std::cout << "XFeat front end on EuRoC V1_01: " << depths.size() << " of " << frame.size()
            << " keypoints with stereo depth\n";
  EXPECT_GT(depths.size(), 400u);
  std::sort(depths.begin(), depths.end());
  const double median = depths[depths.size() / 2];
  EXPECT_GT(median, 1.0);
  EXPECT_LT(median, 6.0);
  const auto implausible =
      std::count_if(depths.begin(), depths.end(), [](double d) { return d < 0.5 || d > 10.0; });
  EXPECT_LT(static_cast<double>(implausible), 0.05 * static_cast<double>(depths.size()));
}

/// Whether two frames carry the same features, bit for bit, and the same stereo depths.
void expectSameFrames(const Frame& a, const Frame& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.features.keypoints[i].pixel, b.features.keypoints[i].pixel) << i;
    EXPECT_EQ(a.features.keypoints[i].response, b.features.keypoints[i].response) << i;
    EXPECT_EQ(a.depth_m[i], b.depth_m[i]) << i;
  }
  ASSERT_EQ(a.features.descriptors.size(), b.features.descriptors.size());
  EXPECT_EQ(cv::norm(a.features.descriptors, b.features.descriptors, cv::NORM_INF), 0.0);
  EXPECT_EQ(a.numStereo(), b.numStereo());
}

/// Frames of the first `count` stereo bundles of the EuRoC excerpt with right images extracted
/// on the helper thread, or one after the other.
std::vector<Frame> eurocFrames(const std::filesystem::path& path, FrontEndOptions options,
                               bool parallel, std::size_t count) {
  options.parallel_extraction = parallel;
  FrontEnd front_end = eurocFrontEnd(path, options);
  io::DatasetSourceOptions source_options;
  source_options.inertial = false;
  source_options.max_frames = count;
  const auto source = io::openDataset(io::DatasetKind::kEuroc, path, source_options);
  std::vector<Frame> frames;
  while (const auto bundle = source->next())
    frames.push_back(front_end.build(*bundle));
  EXPECT_EQ(front_end.helperCpuMs() > 0.0, parallel);
  return frames;
}

TEST(FrontEnd, ParallelExtractionGivesTheFeaturesOfSequentialExtraction) {
  SUPERDYNA_REQUIRE_SHARED(path, kEuroc);
  std::vector<FrontEndOptions> configurations(1);  // ORB
  if (const auto model = test::optionalSharedPath("models/xfeat.onnx", "ORB only");
      !model.empty()) {
    configurations.emplace_back();
    configurations.back().features.type = features::FeatureType::kXFeat;
    configurations.back().features.model = model.string();
  }
  for (const FrontEndOptions& options : configurations) {
    SCOPED_TRACE(features::toString(options.features.type));
    const std::vector<Frame> sequential = eurocFrames(path, options, false, 2);
    const std::vector<Frame> parallel = eurocFrames(path, options, true, 2);
    ASSERT_EQ(sequential.size(), 2u);
    ASSERT_EQ(parallel.size(), 2u);
    for (std::size_t k = 0; k < sequential.size(); ++k)
      expectSameFrames(sequential[k], parallel[k]);
    EXPECT_GT(parallel.back().numStereo(), 100);
  }
}

}  // namespace
}  // namespace superdyna::tracking

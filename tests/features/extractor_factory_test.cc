#include "superdyna/features/extractor_factory.h"

#include <gtest/gtest.h>

#include <string>

#include "superdyna/inference/model_files.h"
#include "support/test_support.h"

namespace superdyna::features {
namespace {

TEST(ExtractorFactory, ParsesTypesAndDescribesTheirPyramids) {
  EXPECT_EQ(parseFeatureType("orb"), FeatureType::kOrb);
  EXPECT_EQ(parseFeatureType("xfeat"), FeatureType::kXFeat);
  EXPECT_EQ(parseFeatureType("superpoint"), FeatureType::kSuperPoint);
  test::expectError<OptionError>([] { parseFeatureType("sift", "--features"); },
                                 {"--features", "sift", "orb | xfeat | superpoint"});
  EXPECT_EQ(toString(FeatureType::kSuperPoint), "superpoint");

  FeatureOptions options;
  options.orb.levels = 6;
  options.orb.scale_factor = 1.25;
  EXPECT_EQ(pyramidOf(options).levels, 6);
  EXPECT_EQ(pyramidOf(options).scale_factor, 1.25);
  EXPECT_EQ(options.modelName(), "");
  options.type = FeatureType::kXFeat;
  EXPECT_EQ(pyramidOf(options).levels, 1);
  EXPECT_EQ(pyramidOf(options).scale_factor, 1.0);
  EXPECT_EQ(options.modelName(), "xfeat.onnx");
  options.type = FeatureType::kSuperPoint;
  EXPECT_EQ(options.modelName(), "superpoint.onnx");
  options.model = "exports/sp.onnx";
  EXPECT_EQ(options.modelName(), "exports/sp.onnx");
}

TEST(ExtractorFactory, BuildsOrbAndRejectsBadOptions) {
  FeatureOptions options;
  const auto orb = makeExtractor(options);
  EXPECT_EQ(orb->name(), "orb");
  options.max_keypoints = 0;
  test::expectError<OptionError>([&] { makeExtractor(options); }, {"features.max_keypoints"});
  options.max_keypoints = 100;
  options.inference_threads = 0;
  test::expectError<OptionError>([&] { makeExtractor(options); }, {"features.inference_threads"});
}

TEST(ExtractorFactory, MissingModelSaysWhereItLookedAndHowToGetOne) {
  const test::ScratchDir empty("factory_no_models");
  const test::ScopedEnv env(inference::kModelDirVariable, empty.path().string());
  FeatureOptions options;
  options.type = FeatureType::kSuperPoint;
  test::expectError([&] { makeExtractor(options); },
                    {"superpoint.onnx", "not found", empty.path().string(),
                     inference::kModelDirVariable, "docs/concepts/learned-features.md"});
}

TEST(ExtractorFactory, BuildsXFeatFromTheSharedModel) {
  SUPERDYNA_REQUIRE_SHARED(models, "models/xfeat.onnx");
  const test::ScopedEnv env(inference::kModelDirVariable, models.parent_path().string());
  FeatureOptions options;
  options.type = FeatureType::kXFeat;
  options.max_keypoints = 300;
  const auto xfeat = makeExtractor(options);
  EXPECT_EQ(xfeat->name(), "xfeat");
  cv::Mat image(96, 128, CV_8UC1);
  cv::RNG rng(3);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  const FeatureSet features = xfeat->extract(image);
  EXPECT_EQ(features.descriptor_type, DescriptorType::kFloat);
  EXPECT_GT(features.size(), 50u);
  EXPECT_LE(features.size(), 300u);
  EXPECT_FALSE(features.keypoints.front().angle >= 0.0f);
}

}  // namespace
}  // namespace superdyna::features

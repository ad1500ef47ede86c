#include "superdyna/features/alike_extractor.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <opencv2/imgproc.hpp>

#include "learned_test_image.h"
#include "superdyna/core/error.h"
#include "superdyna/features/extractor_factory.h"
#include "support/test_support.h"

namespace superdyna::features {
namespace {

using test::syntheticImage;

/// A score map holding one Gaussian peak centred at (cx, cy), sigma 1.2 px.
cv::Mat gaussianPeak(double cx, double cy) {
  cv::Mat scores(20, 24, CV_32FC1);
  for (int y = 0; y < scores.rows; ++y)
    for (int x = 0; x < scores.cols; ++x)
      scores.at<float>(y, x) = static_cast<float>(
          0.9 * std::exp(-((x - cx) * (x - cx) + (y - cy) * (y - cy)) / (2.0 * 1.2 * 1.2)));
  return scores;
}

TEST(SoftArgmaxTest, MovesTheIntegerMaximumTowardsTheTruePeak) {
  // A peak on a pixel stays there; one between pixels moves the estimate off the integer
  // maximum to it; a high temperature flattens the weights towards the window's centre.
  EXPECT_LT((refineSoftArgmax(gaussianPeak(10.0, 8.0), {{10, 8, 0.9f}}, 2, 0.1f)[0] -
             Eigen::Vector2d(10.0, 8.0))
                .norm(),
            1e-9);
  const cv::Mat off = gaussianPeak(10.4, 7.7);
  const Eigen::Vector2d sharp = refineSoftArgmax(off, {{10, 8, 0.9f}}, 2, 0.1f)[0];
  const Eigen::Vector2d flat = refineSoftArgmax(off, {{10, 8, 0.9f}}, 2, 100.0f)[0];
  EXPECT_LT((sharp - Eigen::Vector2d(10.4, 7.7)).norm(), 0.1) << sharp.transpose();
  EXPECT_LT((flat - Eigen::Vector2d(10.0, 8.0)).norm(), 0.01) << flat.transpose();
  EXPECT_THROW(refineSoftArgmax(off, {{10, 8, 0.9f}}, 2, 0.0f), OptionError);
  // Windows are clipped at the map border.
  const Eigen::Vector2d corner =
      refineSoftArgmax(gaussianPeak(0.0, 0.0), {{0, 0, 0.9f}}, 2, 0.1f)[0];
  EXPECT_GE(corner.minCoeff(), 0.0);
}

TEST(AlikeExtractorTest, OptionsAndFactory) {
  EXPECT_EQ(parseFeatureType("alike"), FeatureType::kAlike);
  EXPECT_EQ(toString(FeatureType::kAlike), "alike");
  FeatureOptions options;
  options.type = FeatureType::kAlike;
  EXPECT_EQ(options.modelName(), "alike-t.onnx");
  AlikeOptions bad;
  bad.radius = 0;
  test::expectError<OptionError>([&] { bad.validate(); }, {"radius"});
  bad.radius = 2;
  bad.temperature = -1.0f;
  test::expectError<OptionError>([&] { bad.validate(); }, {"temperature"});
}

TEST(AlikeExtractorTest, XFeatIsRejectedWithAClearMessage) {
  SUPERDYNA_REQUIRE_SHARED(xfeat, "models/xfeat.onnx");
  AlikeOptions options;
  options.model = xfeat.string();
  test::expectError([&] { AlikeExtractor{options}; },
                    {"xfeat.onnx", "does not fit the ALIKE contract", "scores_map"});
}

/// Every shipped variant: unit descriptors of the variant's width, keypoints that move with the
/// image to within a pixel (sub-pixel positions), most of them found again.
TEST(AlikeExtractorTest, ShippedVariantsFindTheSameKeypointsInAShiftedImage) {
  const cv::Mat big = syntheticImage(420, 340, 9);
  const cv::Mat a = big(cv::Rect(13, 7, 384, 320)).clone();
  const cv::Mat b = big(cv::Rect(0, 0, 384, 320)).clone();
  const Eigen::Vector2d shift(13.0, 7.0);
  for (const auto& [name, width] : std::vector<std::pair<std::string, int>>{
           {"alike-t.onnx", 64}, {"alike-s.onnx", 96}, {"alike-n.onnx", 128}}) {
    SCOPED_TRACE(name);
    SUPERDYNA_REQUIRE_SHARED(model, "models/" + name);
    AlikeOptions options;
    options.model = model.string();
    options.max_keypoints = 600;
    AlikeExtractor extractor(options);
    const FeatureSet fa = extractor.extract(a), fb = extractor.extract(b);
    fa.validate();
    ASSERT_GT(fa.size(), 200u);
    EXPECT_LE(fa.size(), 600u);
    EXPECT_EQ(fa.descriptorLength(), width);
    for (int i = 0; i < fa.descriptors.rows; ++i)
      ASSERT_NEAR(cv::norm(fa.descriptors.row(i)), 1.0, 1e-4);
    std::size_t inside = 0, repeated = 0;
    std::vector<double> errors;
    for (const Keypoint& k : fa.keypoints) {
      const Eigen::Vector2d expected = k.pixel + shift;
      if (expected.x() < 8 || expected.y() < 8 || expected.x() > 376 || expected.y() > 312)
        continue;
      ++inside;
      double best = 1e9;
      for (const Keypoint& o : fb.keypoints)
        best = std::min(best, (o.pixel - expected).norm());
      if (best <= 1.0) {
        ++repeated;
        errors.push_back(best);
      }
    }
    std::sort(errors.begin(), errors.end());
    const double median = errors.empty() ? 1e9 : errors[errors.size() / 2];
    std::cout << name << ": " << fa.size() << " keypoints, " << repeated << " of " << inside
              << " found again within 1 px, median error " << median << " px, "
              << extractor.lastExtractMs() << " ms\n";
    EXPECT_GT(static_cast<double>(repeated), 0.7 * static_cast<double>(inside));
    EXPECT_LT(median, 0.25);  // sub-pixel: integer maxima would sit 0 or >= 1 px off
  }
}

TEST(AlikeExtractorTest, AHalfScaleInputGivesKeypointsInFullResolutionPixels) {
  SUPERDYNA_REQUIRE_SHARED(model, "models/alike-t.onnx");
  const cv::Mat image = syntheticImage(384, 320, 9);
  AlikeOptions full_options;
  full_options.model = model.string();
  full_options.max_keypoints = 300;
  AlikeOptions half_options = full_options;
  half_options.input_scale = 0.5;
  AlikeExtractor full(full_options), half(half_options);
  const FeatureSet f = full.extract(image), h = half.extract(image);
  h.validate();
  ASSERT_GT(h.size(), 100u);
  // Every half-scale keypoint lies in the full image, most within 1.5 px of a full-scale one
  // (a wrong mapping back, e.g. half-scale pixels taken as full ones, finds almost none).
  std::size_t near = 0;
  for (const Keypoint& k : h.keypoints) {
    ASSERT_GE(k.pixel.x(), 0.0);
    ASSERT_LT(k.pixel.x(), 384.0);
    ASSERT_LT(k.pixel.y(), 320.0);
    double best = 1e9;
    for (const Keypoint& o : f.keypoints)
      best = std::min(best, (o.pixel - k.pixel).norm());
    if (best <= 1.5) ++near;
  }
  std::cout << near << " of " << h.size()
            << " half-scale keypoints within 1.5 px of a full-scale one\n";
  EXPECT_GT(static_cast<double>(near), 0.4 * static_cast<double>(h.size()));
  AlikeOptions bad = full_options;
  bad.input_scale = 0.0;
  test::expectError<OptionError>([&] { AlikeExtractor{bad}; }, {"input_scale"});
}

}  // namespace
}  // namespace superdyna::features

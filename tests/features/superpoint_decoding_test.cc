// Unit tests of the decoding steps shared by SuperPointExtractor and XFeatExtractor
// (keypoint_decoding.h), on hand-made maps with known answers.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "superdyna/core/error.h"
#include "superdyna/features/keypoint_decoding.h"
#include "support/test_support.h"

namespace superdyna::features {
namespace {

using test::expectError;

/// A [channels, rows, cols] buffer with a DenseMap view of it.
struct Buffer {
  Buffer(int channels, int rows, int cols, float value = 0.0f)
      : data(static_cast<std::size_t>(channels * rows * cols), value),
        map{nullptr, channels, rows, cols} {
    map.data = data.data();
  }
  float& at(int c, int y, int x) {
    return data[(static_cast<std::size_t>(c) * map.rows + y) * map.cols + x];
  }
  std::vector<float> data;
  DenseMap map;
};

TEST(KeypointDecoding, HeatmapPutsEachChannelOnItsPixelOfTheCell) {
  Buffer logits(65, 2, 3);
  // Cell (row 1, col 2): channel 8 * 3 + 5 dominates -> pixel (x = 2 * 8 + 5, y = 1 * 8 + 3).
  logits.at(8 * 3 + 5, 1, 2) = 20.0f;
  // Cell (0, 0): the dustbin dominates.
  logits.at(64, 0, 0) = 20.0f;
  const cv::Mat heat = cellLogitsToHeatmap(logits.map);
  ASSERT_EQ(heat.size(), cv::Size(24, 16));
  ASSERT_EQ(heat.type(), CV_32FC1);
  cv::Point max_at;
  double max_value = 0.0;
  cv::minMaxLoc(heat, nullptr, &max_value, nullptr, &max_at);
  EXPECT_EQ(max_at, cv::Point(21, 11));
  const double e20 = std::exp(20.0);
  EXPECT_NEAR(max_value, e20 / (e20 + 64.0), 1e-6);
  // Uniform logits: every pixel gets 1/65; a cell whose dustbin wins has almost no heat.
  EXPECT_NEAR(heat.at<float>(3, 12), 1.0 / 65.0, 1e-7);
  EXPECT_NEAR(cv::sum(heat(cv::Rect(0, 0, 8, 8)))[0], 64.0 / (e20 + 64.0), 1e-9);
  EXPECT_NEAR(cv::sum(heat(cv::Rect(8, 0, 8, 8)))[0], 64.0 / 65.0, 1e-5);

  Buffer wrong(64, 2, 2);
  expectError([&] { cellLogitsToHeatmap(wrong.map); }, {"64 channels, expected 65"});
}

TEST(KeypointDecoding, LocalMaximaActLikeAMaxPoolWithThreshold) {
  cv::Mat heat(12, 12, CV_32FC1, cv::Scalar(0.0f));
  heat.at<float>(5, 5) = 0.9f;
  heat.at<float>(5, 7) = 0.8f;   // 2 px away: inside the 5x5 window of the first
  heat.at<float>(5, 8) = 0.7f;   // 3 px away from the first, 1 px from the second
  heat.at<float>(0, 11) = 0.5f;  // at the corner: max-pool padding never beats it
  heat.at<float>(10, 2) = 0.3f;  // a plateau of two equal maxima: both kept
  heat.at<float>(10, 3) = 0.3f;
  heat.at<float>(2, 1) = 0.05f;  // not above the threshold
  const auto points = localMaxima(heat, 5, 0.05f);
  ASSERT_EQ(points.size(), 4u);  // row-major order
  EXPECT_EQ(points[0].x, 11);
  EXPECT_EQ(points[0].y, 0);
  EXPECT_EQ(points[1].x, 5);
  EXPECT_FLOAT_EQ(points[1].score, 0.9f);
  EXPECT_EQ(points[2].x, 2);
  EXPECT_EQ(points[3].x, 3);
  // The point 3 px away survives a 5x5 window only when its 1 px neighbour is gone.
  heat.at<float>(5, 7) = 0.0f;
  EXPECT_EQ(localMaxima(heat, 5, 0.05f).size(), 5u);
  // A submatrix is pooled on its own: the parent's pixels beyond its edge do not count.
  heat.at<float>(9, 6) = 0.4f;  // suppressed in `heat` by its right neighbour ...
  heat.at<float>(9, 7) = 0.6f;
  EXPECT_EQ(localMaxima(heat, 5, 0.05f).size(), 6u);
  const cv::Mat left = heat(cv::Rect(0, 0, 7, 12));  // ... which this submatrix does not hold
  const auto sub = localMaxima(left, 5, 0.05f);
  ASSERT_EQ(sub.size(), 4u);
  EXPECT_EQ(sub[1].x, 6);
  EXPECT_EQ(sub[1].y, 9);
  expectError<OptionError>([&] { localMaxima(heat, 4, 0.0f); }, {"nms_window"});
}

/// Logits of a rows x cols grid of 8x8 cells from a seeded generator: a dustbin that wins in
/// most cells, and pixel logits of which some come close to or beat it.
Buffer randomCellLogits(int rows, int cols, unsigned seed) {
  Buffer logits(65, rows, cols);
  std::mt19937 rng(seed);
  std::normal_distribution<float> pixel(0.0f, 1.5f), dustbin(6.0f, 3.0f);
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      for (int c = 0; c < 64; ++c)
        logits.at(c, i, j) = pixel(rng);
      logits.at(64, i, j) = dustbin(rng);
    }
  }
  return logits;
}

TEST(KeypointDecoding, SkippingColdCellsKeepsEveryPixelAboveTheThresholdExact) {
  const Buffer logits = randomCellLogits(30, 40, 7);
  const float threshold = 0.05f;
  const cv::Mat full = cellLogitsToHeatmap(logits.map);
  const cv::Mat fast = cellLogitsToHeatmap(logits.map, 8, threshold);
  ASSERT_EQ(fast.size(), full.size());
  int hot = 0, skipped = 0;
  for (int y = 0; y < full.rows; ++y) {
    for (int x = 0; x < full.cols; ++x) {
      const float f = full.at<float>(y, x), s = fast.at<float>(y, x);
      if (f > threshold) {
        ++hot;
        ASSERT_EQ(s, f) << x << ", " << y;  // bit for bit
      } else {
        ASSERT_TRUE(s == f || s == 0.0f) << x << ", " << y;
        if (s != f) ++skipped;
      }
    }
  }
  // The data exercise both kinds of cells.
  EXPECT_GT(hot, 50);
  EXPECT_GT(skipped, full.rows * full.cols / 4);
  // Hence the same maxima with the same scores, in the same order.
  const auto expected = localMaxima(full, 5, threshold);
  const auto actual = localMaxima(fast, 5, threshold);
  ASSERT_EQ(actual.size(), expected.size());
  for (std::size_t k = 0; k < expected.size(); ++k) {
    EXPECT_EQ(actual[k].x, expected[k].x);
    EXPECT_EQ(actual[k].y, expected[k].y);
    EXPECT_EQ(actual[k].score, expected[k].score);
  }
  // No skipping without a threshold.
  EXPECT_EQ(cv::norm(cellLogitsToHeatmap(logits.map, 8, 0.0f), full, cv::NORM_INF), 0.0);
}

TEST(KeypointDecoding, TopKEqualsTheHeadOfTheFullOrderIncludingTies) {
  std::vector<ScoredPixel> points;
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> score(0, 20);  // few distinct scores: many ties
  for (int y = 0; y < 30; ++y)
    for (int x = 0; x < 30; ++x)
      points.push_back({x, y, 0.05f * static_cast<float>(score(rng))});
  std::shuffle(points.begin(), points.end(), rng);
  std::vector<ScoredPixel> sorted = points;
  sortByScore(sorted);
  const auto top = selectTopK(points, 100);
  ASSERT_EQ(top.size(), 100u);
  for (std::size_t k = 0; k < top.size(); ++k) {
    EXPECT_EQ(top[k].x, sorted[k].x) << k;
    EXPECT_EQ(top[k].y, sorted[k].y) << k;
    EXPECT_EQ(top[k].score, sorted[k].score) << k;
  }
}

TEST(KeypointDecoding, GreedyNmsSuppressesSquaresAroundKeptPointsOnly) {
  const std::vector<ScoredPixel> candidates = {{13, 10, 0.8f}, {10, 10, 0.9f}, {15, 10, 0.7f},
                                               {10, 14, 0.6f}, {10, 15, 0.6f}, {30, 30, 0.6f}};
  const auto kept = suppressNonMaxima(candidates, 4, {40, 40});
  // (13,10) falls in the square of (10,10); (15,10) only in that of the suppressed (13,10);
  // (10,14) is within 4 px of (10,10) in both axes; (10,15) is not.
  ASSERT_EQ(kept.size(), 4u);
  EXPECT_EQ(kept[0].x, 10);
  EXPECT_EQ(kept[0].y, 10);
  EXPECT_EQ(kept[1].x, 15);
  // Equal scores: by row, then column.
  EXPECT_EQ(kept[2].y, 15);
  EXPECT_EQ(kept[3].x, 30);
  EXPECT_EQ(suppressNonMaxima(candidates, 0, {40, 40}).size(), candidates.size());
  expectError([&] { suppressNonMaxima({{50, 1, 1.0f}}, 4, {40, 40}); }, {"outside"});
}

TEST(KeypointDecoding, BorderAndTopKSelection) {
  const std::vector<ScoredPixel> points = {
      {3, 10, 0.1f}, {4, 10, 0.2f}, {15, 15, 0.3f}, {16, 10, 0.4f}, {10, 3, 0.5f}};
  const auto inside = keepInside(points, 4, {20, 20});
  ASSERT_EQ(inside.size(), 2u);  // x = 4 and x = 15 stay; 16 >= 20 - 4 and y = 3 go
  EXPECT_EQ(inside[0].x, 4);
  EXPECT_EQ(inside[1].x, 15);

  // Cell (0,0) of a 10 px grid holds the four best points; three other cells one each.
  std::vector<ScoredPixel> many = {{1, 1, 0.99f}, {2, 2, 0.98f}, {3, 3, 0.97f}, {4, 4, 0.96f},
                                   {15, 1, 0.2f}, {1, 15, 0.3f}, {15, 15, 0.1f}};
  const auto best = selectTopK(many, 4);
  ASSERT_EQ(best.size(), 4u);
  EXPECT_FLOAT_EQ(best[3].score, 0.96f);
  const auto spread = selectTopK(many, 4, 10);
  ASSERT_EQ(spread.size(), 4u);  // every cell's best first, then sorted by score
  EXPECT_FLOAT_EQ(spread[0].score, 0.99f);
  EXPECT_FLOAT_EQ(spread[1].score, 0.3f);
  EXPECT_FLOAT_EQ(spread[2].score, 0.2f);
  EXPECT_FLOAT_EQ(spread[3].score, 0.1f);
  const auto five = selectTopK(many, 5, 10);
  EXPECT_FLOAT_EQ(five[1].score, 0.98f);
  EXPECT_EQ(selectTopK(many, 0).size(), many.size());
}

TEST(KeypointDecoding, SubpixelRefinementRecoversTheCentreOfASymmetricPeak) {
  // A Gaussian blob centred at (12.3, 7.6) sampled on pixel centres: the integer maximum is
  // (12, 8); the centroid of the 5x5 window above its floor lies close to the true centre.
  cv::Mat heatmap(16, 24, CV_32FC1);
  const double cx = 12.3, cy = 7.6, sigma = 0.8;
  for (int y = 0; y < heatmap.rows; ++y) {
    for (int x = 0; x < heatmap.cols; ++x) {
      const double r2 = (x - cx) * (x - cx) + (y - cy) * (y - cy);
      heatmap.at<float>(y, x) = static_cast<float>(std::exp(-r2 / (2 * sigma * sigma)));
    }
  }
  const std::vector<ScoredPixel> peak = localMaxima(heatmap, 5, 0.05f);
  ASSERT_EQ(peak.size(), 1u);
  EXPECT_EQ(peak[0].x, 12);
  EXPECT_EQ(peak[0].y, 8);
  const Eigen::Vector2d refined = refineSubpixel(heatmap, peak, 2).front();
  EXPECT_NEAR(refined.x(), cx, 0.05);
  EXPECT_NEAR(refined.y(), cy, 0.05);
  // A 3x3 window is biased towards the integer maximum but still on the right side of it.
  const Eigen::Vector2d small = refineSubpixel(heatmap, peak, 1).front();
  EXPECT_GT(small.x(), 12.1);
  EXPECT_LT(small.x(), cx + 0.05);
  EXPECT_LT(small.y(), 7.9);
  EXPECT_GT(small.y(), cy - 0.05);

  // Radius 0 and a flat window keep the integer pixel; windows are clipped at the border.
  EXPECT_EQ(refineSubpixel(heatmap, peak, 0).front(), Eigen::Vector2d(12.0, 8.0));
  const cv::Mat flat(4, 4, CV_32FC1, cv::Scalar(0.5));
  EXPECT_EQ(refineSubpixel(flat, {{1, 2, 0.5f}}, 2).front(), Eigen::Vector2d(1.0, 2.0));
  cv::Mat corner = cv::Mat::zeros(4, 4, CV_32FC1);
  corner.at<float>(0, 0) = 1.0f;
  corner.at<float>(0, 1) = 1.0f;
  EXPECT_EQ(refineSubpixel(corner, {{0, 0, 1.0f}}, 1).front(), Eigen::Vector2d(0.5, 0.0));
  expectError<OptionError>([&] { refineSubpixel(heatmap, peak, -1); }, {"subpixel_radius", "-1"});
}

TEST(KeypointDecoding, PixelCentreConventionAndBilinearSampling) {
  // The centre of cell 0 (pixels 0..7) is pixel 3.5; pixel 0 lies 7/16 cell before it.
  EXPECT_DOUBLE_EQ(pixelToMap({3.5, 11.5}, 8).x(), 0.0);
  EXPECT_DOUBLE_EQ(pixelToMap({3.5, 11.5}, 8).y(), 1.0);
  EXPECT_DOUBLE_EQ(pixelToMap({0.0, 0.0}, 8).x(), -0.4375);

  // A map linear in (u, v): bilinear sampling reproduces it inside, clamps outside.
  Buffer ramp(2, 3, 4);
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 4; ++x) {
      ramp.at(0, y, x) = static_cast<float>(2 * x + 10 * y);
      ramp.at(1, y, x) = 1.0f;
    }
  }
  EXPECT_NEAR(sampleBilinear(ramp.map, 0, 1.25, 0.5), 2.5 + 5.0, 1e-6);
  EXPECT_NEAR(sampleBilinear(ramp.map, 0, -3.0, 0.0), 0.0, 1e-6);
  EXPECT_NEAR(sampleBilinear(ramp.map, 0, 7.0, 9.0), 6.0 + 20.0, 1e-6);

  // Descriptors: sampled at the pixel's map coordinate, then unit length.
  const cv::Mat d = sampleDescriptors(ramp.map, {{11.5, 3.5}}, 8);  // map (1, 0): values 2 and 1
  ASSERT_EQ(d.size(), cv::Size(2, 1));
  EXPECT_NEAR(d.at<float>(0, 0), 2.0 / std::sqrt(5.0), 1e-6);
  EXPECT_NEAR(d.at<float>(0, 1), 1.0 / std::sqrt(5.0), 1e-6);
  Buffer zero(3, 2, 2);
  EXPECT_EQ(cv::norm(sampleDescriptors(zero.map, {{4.0, 4.0}}, 8)), 0.0);

  const std::vector<float> unit = normalizeCells(ramp.map);
  const DenseMap unit_map{unit.data(), 2, 3, 4};
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 4; ++x) {
      EXPECT_NEAR(std::hypot(unit_map.at(0, y, x), unit_map.at(1, y, x)), 1.0, 1e-6);
    }
  }
}

TEST(KeypointDecoding, FitsImagesByPaddingOrResizingAndMapsPixelsBack) {
  const ImageFit pad = planFit({752, 480}, 32, FitMode::kPad);
  EXPECT_EQ(pad.network, cv::Size(768, 480));
  EXPECT_EQ(pad.valid(), cv::Size(752, 480));
  EXPECT_EQ(pad.toOriginal({100.0, 50.0}), Eigen::Vector2d(100.0, 50.0));
  const ImageFit resize = planFit({752, 480}, 32, FitMode::kResize);
  EXPECT_EQ(resize.network, cv::Size(736, 480));
  EXPECT_EQ(resize.valid(), cv::Size(736, 480));
  // Centre to centre; pixel centres map onto pixel centres.
  EXPECT_NEAR(resize.toOriginal({367.5, 239.5}).x(), 375.5, 1e-12);
  EXPECT_NEAR(resize.toOriginal({367.5, 239.5}).y(), 239.5, 1e-12);
  EXPECT_EQ(planFit({20, 10}, 32, FitMode::kResize).network, cv::Size(32, 32));
  expectError<OptionError>([] { planFit({10, 10}, 0, FitMode::kPad); }, {"multiple"});
  expectError([] { planFit({0, 10}, 8, FitMode::kPad); }, {"empty image"});

  cv::Mat image(5, 6, CV_8UC1);
  for (int i = 0; i < 30; ++i)
    image.data[i] = static_cast<std::uint8_t>(i * 7);
  const cv::Mat padded = applyFit(image, planFit(image.size(), 8, FitMode::kPad));
  ASSERT_EQ(padded.size(), cv::Size(8, 8));
  EXPECT_EQ(padded.at<std::uint8_t>(0, 6), image.at<std::uint8_t>(0, 4));  // reflected
  EXPECT_EQ(padded.at<std::uint8_t>(5, 2), image.at<std::uint8_t>(3, 2));
  EXPECT_EQ(padded.at<std::uint8_t>(2, 3), image.at<std::uint8_t>(2, 3));  // unchanged inside
}

TEST(KeypointDecoding, AScaledFitMapsPixelCentresBackToTheFullImage) {
  const ImageFit half = planFit({752, 480}, 32, FitMode::kPad, 0.5);
  EXPECT_EQ(half.content, cv::Size(376, 240));
  EXPECT_EQ(half.network, cv::Size(384, 256));
  EXPECT_EQ(half.valid(), cv::Size(376, 240));
  // Network pixel 0 covers original pixels 0 and 1: its centre is 0.5; pixel 187 covers 374, 375.
  EXPECT_NEAR(half.toOriginal({0.0, 0.0}).x(), 0.5, 1e-12);
  EXPECT_NEAR(half.toOriginal({187.0, 119.0}).x(), 374.5, 1e-12);
  EXPECT_NEAR(half.toOriginal({187.0, 119.0}).y(), 238.5, 1e-12);
  EXPECT_EQ(half.pixelScale().x(), 2.0);
  const ImageFit resized = planFit({752, 480}, 32, FitMode::kResize, 0.5);
  EXPECT_EQ(resized.network, cv::Size(352, 224));
  EXPECT_EQ(resized.valid(), resized.network);
  expectError<OptionError>([] { planFit({10, 10}, 8, FitMode::kPad, 0.0); }, {"input_scale"});
  expectError<OptionError>([] { planFit({10, 10}, 8, FitMode::kPad, 1.5); }, {"input_scale"});

  // A bright 2x2 block at original pixels (10..11, 6..7) is one pixel at (5, 3) of the half
  // image, and maps back onto the block's centre.
  cv::Mat image(16, 24, CV_8UC1, cv::Scalar(0));
  image(cv::Rect(10, 6, 2, 2)).setTo(200);
  const ImageFit fit = planFit(image.size(), 8, FitMode::kPad, 0.5);
  const cv::Mat small = applyFit(image, fit);
  ASSERT_EQ(small.size(), cv::Size(16, 8));
  EXPECT_EQ(small.at<std::uint8_t>(3, 5), 200);
  EXPECT_EQ(small.at<std::uint8_t>(3, 4), 0);
  EXPECT_EQ(fit.toOriginal({5.0, 3.0}), Eigen::Vector2d(10.5, 6.5));

  // Scaled and padded back to the original size: still scaled, not the image as it was.
  cv::Mat ramp(32, 64, CV_8UC1);
  for (int x = 0; x < 64; ++x)
    ramp.col(x).setTo(x * 4);
  const ImageFit same_size = planFit(ramp.size(), 32, FitMode::kPad, 0.9);
  ASSERT_EQ(same_size.network, ramp.size());
  EXPECT_EQ(same_size.content, cv::Size(58, 29));
  const cv::Mat refitted = applyFit(ramp, same_size);
  EXPECT_GT(cv::norm(refitted, ramp, cv::NORM_INF), 8.0);
}

}  // namespace
}  // namespace superdyna::features

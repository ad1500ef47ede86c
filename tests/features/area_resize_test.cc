#include "superdyna/features/area_resize.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>

#include "superdyna/core/error.h"

namespace superdyna::features {
namespace {

/// Uniform noise, smoothed a little: sums of many pixels land near every rounding boundary.
cv::Mat noiseImage(cv::Size size, unsigned seed) {
  cv::Mat image(size, CV_8UC1);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> gray(0, 255);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x)
      image.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(gray(rng));
  cv::GaussianBlur(image, image, cv::Size(3, 3), 0.7);
  return image;
}

/// Counts the pixels where AreaShrinker and cv::resize(INTER_AREA) differ; shrinks `from` to
/// `to` on noise and on a flat image (whose mean must come back exactly).
int differingPixels(cv::Size from, cv::Size to, unsigned seed) {
  const AreaShrinker shrinker(from, to);
  const cv::Mat image = noiseImage(from, seed);
  cv::Mat ours, opencv;
  shrinker.apply(image, ours);
  cv::resize(image, opencv, to, 0.0, 0.0, cv::INTER_AREA);
  EXPECT_EQ(ours.size(), to);
  EXPECT_EQ(ours.type(), CV_8UC1);
  return cv::countNonZero(ours != opencv);
}

TEST(AreaShrinkerTest, EqualsOpenCvAreaResizeOnOrbPyramidsOfEveryScaleFactor) {
  // ORB's pyramid: level l is level l - 1 shrunk to round(size0 / factor^l), for the factors
  // the options allow ((1, 2]) and the image sizes of the datasets.
  int levels = 0;
  for (const cv::Size size0 : {cv::Size(752, 480), cv::Size(1241, 376), cv::Size(640, 480)}) {
    for (const double factor : {1.2, 1.1, 1.5, 1.9}) {
      cv::Size from = size0;
      for (int l = 1; l < 8; ++l) {
        const double scale = std::pow(factor, l);
        const cv::Size to(static_cast<int>(std::lround(size0.width / scale)),
                          static_cast<int>(std::lround(size0.height / scale)));
        if (to.width < 1 || to.height < 1) break;
        EXPECT_EQ(differingPixels(from, to, static_cast<unsigned>(l)), 0)
            << from << " -> " << to << " (factor " << factor << ", level " << l << ")";
        from = to;
        ++levels;
      }
    }
  }
  EXPECT_GE(levels, 80);
}

TEST(AreaShrinkerTest, EqualsOpenCvAreaResizeOnOddShapesAndWholeFactors) {
  const std::vector<std::pair<cv::Size, cv::Size>> cases = {
      {{7, 5}, {3, 2}},         {{17, 13}, {16, 12}},     {{100, 100}, {1, 1}},
      {{33, 9}, {33, 4}},       {{9, 33}, {4, 33}},       {{21, 21}, {20, 7}},
      {{640, 480}, {320, 240}}, {{640, 480}, {640, 480}}, {{641, 479}, {213, 97}}};
  for (const auto& [from, to] : cases)
    EXPECT_EQ(differingPixels(from, to, 3), 0) << from << " -> " << to;
}

TEST(AreaShrinkerTest, AveragesTheAreaEachPixelCovers) {
  // 3 -> 2: pixel 0 covers source 0 and half of 1, pixel 1 half of 1 and 2.
  const cv::Mat row = (cv::Mat_<std::uint8_t>(1, 3) << 30, 90, 150);
  cv::Mat out;
  AreaShrinker(cv::Size(3, 1), cv::Size(2, 1)).apply(row, out);
  EXPECT_EQ(out.at<std::uint8_t>(0, 0), 50);   // (30 + 0.5 * 90) / 1.5
  EXPECT_EQ(out.at<std::uint8_t>(0, 1), 130);  // (0.5 * 90 + 150) / 1.5
  const cv::Mat flat(97, 131, CV_8UC1, cv::Scalar(77));
  AreaShrinker(flat.size(), cv::Size(80, 61)).apply(flat, out);
  EXPECT_EQ(cv::countNonZero(out != 77), 0);
}

TEST(AreaShrinkerTest, RefusesGrowingAndImagesOfAnotherSizeOrType) {
  EXPECT_THROW(AreaShrinker(cv::Size(10, 10), cv::Size(11, 10)), InputError);
  EXPECT_THROW(AreaShrinker(cv::Size(10, 10), cv::Size(5, 0)), InputError);
  const AreaShrinker shrinker(cv::Size(10, 10), cv::Size(8, 8));
  cv::Mat out;
  EXPECT_THROW(shrinker.apply(cv::Mat(10, 11, CV_8UC1, cv::Scalar(0)), out), InputError);
  EXPECT_THROW(shrinker.apply(cv::Mat(10, 10, CV_8UC3, cv::Scalar(0)), out), InputError);
}

}  // namespace
}  // namespace superdyna::features

#include "superdyna/features/fast_windows.h"

#include <gtest/gtest.h>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "feature_test_util.h"
#include "superdyna/core/error.h"
#include "superdyna/io/euroc_dataset.h"
#include "support/test_support.h"

namespace superdyna::features {
namespace {

cv::Mat noiseImage(int width, int height, unsigned seed) {
  cv::Mat image(height, width, CV_8UC1);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> gray(0, 255);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      image.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(gray(rng));
  return image;
}

/// Random noise, blurred so that scores spread over the whole range and neighbours tie.
cv::Mat blurredNoise(int width, int height, unsigned seed) {
  cv::Mat image;
  cv::GaussianBlur(noiseImage(width, height, seed), image, cv::Size(3, 3), 0.8);
  return image;
}

/// cv::FAST with suppression on image(window), in image coordinates.
std::vector<cv::KeyPoint> cvFastIn(const cv::Mat& image, const cv::Rect& window, int threshold) {
  std::vector<cv::KeyPoint> found;
  cv::FAST(image(window), found, threshold, true);
  for (cv::KeyPoint& kp : found) {
    kp.pt.x += static_cast<float>(window.x);
    kp.pt.y += static_cast<float>(window.y);
  }
  return found;
}

/// Every field of every keypoint, in order.
void expectSameKeypoints(const std::vector<cv::KeyPoint>& expected,
                         const std::vector<cv::KeyPoint>& actual, const std::string& where) {
  ASSERT_EQ(expected.size(), actual.size()) << where;
  for (std::size_t k = 0; k < expected.size(); ++k) {
    const cv::KeyPoint& e = expected[k];
    const cv::KeyPoint& a = actual[k];
    EXPECT_TRUE(e.pt == a.pt && e.size == a.size && e.angle == a.angle &&
                e.response == a.response && e.octave == a.octave && e.class_id == a.class_id)
        << where << " keypoint " << k << ": cv::FAST (" << e.pt.x << ", " << e.pt.y << ") "
        << e.response << ", FastWindows (" << a.pt.x << ", " << a.pt.y << ") " << a.response;
  }
}

/// Compares FastWindows with per-window cv::FAST on ORB's cell grid (30 px cells overlapping by
/// 6 px, as OrbExtractor::detectCorners) and on random windows of `region`.
void expectWindowsAsCvFast(const cv::Mat& image, const cv::Rect& region, int threshold,
                           const std::string& name) {
  const FastWindows windows(image, region, threshold);
  std::vector<cv::Rect> cells;
  for (int y = region.y; y + 7 <= region.y + region.height; y += 30) {
    for (int x = region.x; x + 7 <= region.x + region.width; x += 30) {
      cells.push_back(cv::Rect(x, y, 36, 36) & region);
    }
  }
  std::mt19937 rng(threshold);
  for (int k = 0; k < 40; ++k) {
    std::uniform_int_distribution<int> px(region.x, region.x + region.width - 7);
    std::uniform_int_distribution<int> py(region.y, region.y + region.height - 7);
    const int x = px(rng), y = py(rng);
    std::uniform_int_distribution<int> w(7, region.x + region.width - x);
    std::uniform_int_distribution<int> h(7, region.y + region.height - y);
    cells.push_back(cv::Rect(x, y, std::min(w(rng), 80), std::min(h(rng), 80)));
  }
  int total = 0;
  for (const cv::Rect& cell : cells) {
    if (cell.width < 7 || cell.height < 7) continue;
    std::vector<cv::KeyPoint> found;
    windows.detect(cell, found);
    const std::vector<cv::KeyPoint> expected = cvFastIn(image, cell, threshold);
    total += static_cast<int>(expected.size());
    expectSameKeypoints(expected, found,
                        name + " threshold " + std::to_string(threshold) + " window " +
                            std::to_string(cell.x) + "," + std::to_string(cell.y) + " " +
                            std::to_string(cell.width) + "x" + std::to_string(cell.height));
  }
  EXPECT_GT(total, 20) << name << " threshold " << threshold << ": too few corners to compare";
}

TEST(FastWindowsTest, ScoreIsTheLargestThresholdAtWhichCvFastFindsTheCorner) {
  const cv::Mat image = blurredNoise(96, 64, 3);
  for (const int threshold : {1, 7, 20, 33, 60}) {
    std::vector<cv::KeyPoint> found;
    cv::FAST(image, found, threshold, false);
    cv::Mat corner = cv::Mat::zeros(image.size(), CV_8UC1);
    for (const cv::KeyPoint& kp : found)
      corner.at<std::uint8_t>(cvRound(kp.pt.y), cvRound(kp.pt.x)) = 1;
    int corners = 0;
    for (int y = 3; y < image.rows - 3; ++y) {
      for (int x = 3; x < image.cols - 3; ++x) {
        const int score =
            fastCornerScore(image.ptr<std::uint8_t>(y) + x, static_cast<int>(image.step1()));
        const bool is_corner = corner.at<std::uint8_t>(y, x) != 0;
        corners += is_corner;
        ASSERT_EQ(is_corner, score >= threshold)
            << "pixel " << x << "," << y << " threshold " << threshold << " score " << score;
      }
    }
    EXPECT_GT(corners, 10) << threshold;
  }
}

TEST(FastWindowsTest, WindowsFindWhatCvFastFindsInEachWindow) {
  const cv::Mat noise = blurredNoise(200, 150, 7);
  const cv::Mat texture = test::texturedImage(320, 240, 11);
  for (const int threshold : {7, 20}) {
    expectWindowsAsCvFast(noise, cv::Rect(0, 0, noise.cols, noise.rows), threshold, "noise");
    expectWindowsAsCvFast(noise, cv::Rect(13, 9, 150, 111), threshold, "noise, inner region");
    expectWindowsAsCvFast(texture, cv::Rect(16, 16, 288, 208), threshold, "texture");
  }
}

TEST(FastWindowsTest, WindowsFindWhatCvFastFindsOnARealImage) {
  const std::filesystem::path euroc = ::superdyna::test::optionalSharedPath(
      "data/euroc/V1_01_easy_micro", "comparing on synthetic images only");
  if (euroc.empty()) GTEST_SKIP() << "EuRoC excerpt not found";
  const io::EurocDataset dataset = io::EurocDataset::open(euroc);
  const cv::Mat image = io::loadImage(dataset.monoFrames().front().path, dataset.cam0Calibration());
  cv::Mat half;
  cv::resize(image, half, cv::Size(), 1.0 / 1.44, 1.0 / 1.44, cv::INTER_AREA);
  for (const int threshold : {7, 20}) {
    expectWindowsAsCvFast(image, cv::Rect(16, 16, image.cols - 32, image.rows - 32), threshold,
                          "EuRoC cam0");
    expectWindowsAsCvFast(half, cv::Rect(16, 16, half.cols - 32, half.rows - 32), threshold,
                          "EuRoC cam0 at 1/1.44");
  }
}

TEST(FastWindowsTest, RejectsARegionOutsideTheImageAndAWindowOutsideTheRegion) {
  const cv::Mat image = noiseImage(40, 30, 1);
  EXPECT_THROW(FastWindows(image, cv::Rect(10, 10, 40, 10), 20), InputError);
  EXPECT_THROW(FastWindows(image, cv::Rect(0, 0, 40, 30), 0), InputError);
  const FastWindows windows(image, cv::Rect(5, 5, 30, 20), 20);
  std::vector<cv::KeyPoint> corners;
  EXPECT_THROW(windows.detect(cv::Rect(0, 0, 20, 20), corners), InputError);
}

}  // namespace
}  // namespace superdyna::features

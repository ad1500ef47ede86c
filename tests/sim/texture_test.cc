#include "superdyna/sim/texture.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "superdyna/core/error.h"

namespace superdyna::sim {
namespace {

Texture makeProcedural(TextureStyle style, std::uint64_t seed, int width = 1024, int height = 768,
                       double texel_m = 0.01) {
  ProceduralTextureOptions options;
  options.style = style;
  options.seed = seed;
  options.width = width;
  options.height = height;
  options.texel_m = texel_m;
  return Texture::procedural(options);
}

double meanAbsDifference(const cv::Mat& a, const cv::Mat& b) {
  return cv::norm(a, b, cv::NORM_L1) / static_cast<double>(a.total());
}

const std::vector<TextureStyle> kAllStyles = {TextureStyle::kGround, TextureStyle::kFacade,
                                              TextureStyle::kIndoor, TextureStyle::kVehicle,
                                              TextureStyle::kPedestrian};

TEST(TextureTest, SameSeedGivesTheSameTextureAndOtherSeedsUnrelatedOnes) {
  for (const TextureStyle style : kAllStyles) {
    const Texture a = makeProcedural(style, 7, 512, 512);
    const Texture b = makeProcedural(style, 7, 512, 512);
    const Texture c = makeProcedural(style, 8, 512, 512);
    EXPECT_EQ(cv::norm(a.image(), b.image(), cv::NORM_INF), 0.0) << toString(style);
    // Unrelated 8-bit textures with std ~55 differ by ~50 gray levels on average.
    EXPECT_GT(meanAbsDifference(a.image(), c.image()), 20.0) << toString(style);
  }
}

TEST(TextureTest, ProceduralTexturesHaveManyCornersAndWideContrast) {
  for (const TextureStyle style : kAllStyles) {
    for (const std::uint64_t seed : {1u, 2u, 3u}) {
      const Texture texture = makeProcedural(style, seed);
      const cv::Mat crop = texture.image()(cv::Rect(136, 144, 752, 480));
      std::vector<cv::KeyPoint> corners;
      cv::FAST(crop, corners, 20, true);
      cv::Scalar mean, stddev;
      cv::meanStdDev(crop, mean, stddev);
      RecordProperty(toString(style) + "_fast_" + std::to_string(seed),
                     static_cast<int>(corners.size()));
      std::cout << toString(style) << " seed " << seed << ": " << corners.size()
                << " FAST corners, mean " << mean[0] << ", std " << stddev[0] << "\n";
      EXPECT_GT(corners.size(), 400u) << toString(style) << " seed " << seed;
      EXPECT_GT(stddev[0], 30.0) << toString(style) << " seed " << seed;
      EXPECT_GT(mean[0], 60.0);
      EXPECT_LT(mean[0], 190.0);
    }
  }
}

TEST(TextureTest, ProceduralTextureDoesNotRepeatOverItsExtent) {
  const Texture texture = makeProcedural(TextureStyle::kGround, 5, 2048, 512);
  const cv::Mat template_patch = texture.image()(cv::Rect(100, 100, 128, 128));
  cv::Mat scores;
  cv::matchTemplate(texture.image(), template_patch, scores, cv::TM_CCOEFF_NORMED);
  // Away from the patch itself no place looks like it.
  double worst = -1.0;
  for (int r = 0; r < scores.rows; ++r) {
    for (int c = 0; c < scores.cols; ++c) {
      if (std::abs(r - 100) > 32 || std::abs(c - 100) > 32) {
        worst = std::max(worst, static_cast<double>(scores.at<float>(r, c)));
      }
    }
  }
  EXPECT_LT(worst, 0.5);
}

TEST(TextureTest, LargeTexturesGenerateQuickly) {
  // No timing assertion (machines differ); prints the time for the log.
  for (const TextureStyle style : kAllStyles) {
    const auto start = std::chrono::steady_clock::now();
    const Texture texture = makeProcedural(style, 11, 8000, 2000);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::cout << "8000x2000 " << toString(style) << " texture: " << seconds * 1e3 << " ms\n";
    EXPECT_EQ(texture.width(), 8000);
    EXPECT_EQ(texture.height(), 2000);
    EXPECT_EQ(texture.levelCount(), 14);  // 8000 -> 4000 -> ... -> 1
  }
}

TEST(TextureTest, SampleAtTexelCentresReturnsTheTexels) {
  cv::Mat image(3, 4, CV_8UC1);
  cv::randu(image, 0, 256);
  const Texture texture = Texture::fromImage(image, 0.5);
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      const Eigen::Vector2d centre((c + 0.5) * 0.5, (r + 0.5) * 0.5);
      EXPECT_FLOAT_EQ(texture.sample(centre, 0.0), image.at<std::uint8_t>(r, c));
      // Halfway between two texels: their mean.
      const Eigen::Vector2d between((c + 1.0) * 0.5, (r + 0.5) * 0.5);
      const int next = (c + 1) % image.cols;  // wraps around at the right border
      EXPECT_FLOAT_EQ(texture.sample(between, 0.1),
                      0.5f * (image.at<std::uint8_t>(r, c) + image.at<std::uint8_t>(r, next)));
    }
  }
}

TEST(TextureTest, SamplingWrapsAroundAndIsContinuous) {
  const Texture texture = makeProcedural(TextureStyle::kFacade, 3, 300, 200, 0.02);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> coordinate(-50.0, 50.0);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector2d uv(coordinate(rng), coordinate(rng));
    const Eigen::Vector2d period(texture.widthM(), texture.heightM());
    for (const double footprint : {0.0, 0.05, 0.3, 5.0}) {
      EXPECT_NEAR(texture.sample(uv, footprint),
                  texture.sample(uv + Eigen::Vector2d(period.x() * 3, -period.y()), footprint),
                  1e-3);
    }
  }
  // Along a line through texel borders and the wrap-around seam, in steps of 1/100 texel, the
  // value changes by at most 255 * 0.01 * sqrt(2) (bilinear slope bound).
  const double step_m = 0.01 * texture.texelSizeM();
  double max_step_change = 0.0;
  Eigen::Vector2d uv(texture.widthM() - 1.3, texture.heightM() - 0.9);
  float previous = texture.sample(uv, 0.0);
  for (int i = 0; i < 30000; ++i) {
    uv += Eigen::Vector2d(step_m, 0.6 * step_m);
    const float value = texture.sample(uv, 0.0);
    max_step_change = std::max(max_step_change, static_cast<double>(std::abs(value - previous)));
    previous = value;
  }
  EXPECT_LT(max_step_change, 255.0 * 0.01 * std::sqrt(2.0) + 1e-3);
  // Continuous in the footprint too: the blend between mip levels has no jumps.
  double max_footprint_change = 0.0;
  previous = texture.sample(uv, 0.001);
  for (double footprint = 0.001; footprint < 10.0; footprint *= 1.001) {
    const float value = texture.sample(uv, footprint);
    max_footprint_change =
        std::max(max_footprint_change, static_cast<double>(std::abs(value - previous)));
    previous = value;
  }
  EXPECT_LT(max_footprint_change, 1.0);
}

TEST(TextureTest, LargeFootprintOverHighFrequencyApproachesTheMean) {
  // One-texel checkerboard: point sampling at a large footprint would alias to 0 or 255.
  cv::Mat checker(256, 256, CV_8UC1);
  for (int r = 0; r < checker.rows; ++r) {
    for (int c = 0; c < checker.cols; ++c)
      checker.at<std::uint8_t>(r, c) = (r + c) % 2 ? 255 : 0;
  }
  const Texture texture = Texture::fromImage(checker, 0.01);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coordinate(0.0, 2.56);
  double max_error_fine = 0.0, max_error_coarse = 0.0;
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector2d uv(coordinate(rng), coordinate(rng));
    max_error_fine = std::max(max_error_fine, std::abs(texture.sample(uv, 0.001) - 127.5));
    max_error_coarse = std::max(max_error_coarse, std::abs(texture.sample(uv, 0.64) - 127.5));
  }
  EXPECT_GT(max_error_fine, 100.0);  // the pattern is there at fine scale
  EXPECT_LT(max_error_coarse, 1.0);  // and averages out at 64 texels per pixel
}

TEST(TextureTest, FromImageConvertsColourAndUniformIsConstant) {
  cv::Mat colour(10, 20, CV_8UC3, cv::Scalar(10, 100, 200));
  const Texture texture = Texture::fromImage(colour, 0.1);
  EXPECT_EQ(texture.width(), 20);
  EXPECT_EQ(texture.height(), 10);
  EXPECT_NEAR(texture.sample({0.33, 0.77}, 0.0), 0.114 * 10 + 0.587 * 100 + 0.299 * 200, 1.0);
  const Texture white = Texture::uniform(255.0);
  EXPECT_FLOAT_EQ(white.sample({123.4, -5.6}, 0.0), 255.0f);
  EXPECT_FLOAT_EQ(white.sample({123.4, -5.6}, 100.0), 255.0f);
  EXPECT_FLOAT_EQ(Texture().sample({1.0, 2.0}, 0.5), 128.0f);
}

TEST(TextureTest, WithContrastScalesTheDeviationsFromTheMean) {
  const Texture texture = makeProcedural(TextureStyle::kFacade, 7, 256, 256);
  cv::Scalar mean, deviation;
  cv::meanStdDev(texture.image(), mean, deviation);
  const Texture weak = texture.withContrast(0.3);
  cv::Scalar weak_mean, weak_deviation;
  cv::meanStdDev(weak.image(), weak_mean, weak_deviation);
  EXPECT_NEAR(weak_mean[0], mean[0], 0.5);
  EXPECT_NEAR(weak_deviation[0] / deviation[0], 0.3, 0.01);
  // Each texel moves towards the mean: rounding is the only other change.
  const cv::Point texel(100, 50);
  const double expected = mean[0] + 0.3 * (texture.image().at<std::uint8_t>(texel) - mean[0]);
  EXPECT_NEAR(weak.image().at<std::uint8_t>(texel), expected, 0.5 + 1e-9);
  // The mipmap is rebuilt from the new level 0: a footprint of 4 texels (level 2) is weakened too.
  for (const Eigen::Vector2d& uv : {Eigen::Vector2d(1.0, 1.0), Eigen::Vector2d(0.37, 2.11)}) {
    const double usual = texture.sample(uv, 0.04);
    EXPECT_NEAR(weak.sample(uv, 0.04), mean[0] + 0.3 * (usual - mean[0]), 1.5);
  }
  EXPECT_EQ(cv::norm(texture.withContrast(1.0).image(), texture.image(), cv::NORM_INF), 0.0);
  EXPECT_THROW(texture.withContrast(0.0), OptionError);
  EXPECT_THROW(texture.withContrast(5.0), OptionError);
}

TEST(TextureTest, PhotoMosaicUsesCropsOfThePhotos) {
  // Two "photos": a horizontal ramp 0..99 and a vertical ramp 150..249.
  cv::Mat ramp_x(300, 400, CV_8UC1), ramp_y(300, 400, CV_8UC1);
  for (int r = 0; r < 300; ++r) {
    for (int c = 0; c < 400; ++c) {
      ramp_x.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(c / 4);
      ramp_y.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(150 + r / 3);
    }
  }
  const Texture mosaic = Texture::fromPhotos({ramp_x, ramp_y}, 1500, 700, 0.02, 9);
  EXPECT_EQ(mosaic.width(), 1500);
  EXPECT_EQ(mosaic.height(), 700);
  const cv::Mat& image = mosaic.image();
  // Both photos appear, and nothing else: no value strays between the two ranges.
  EXPECT_GT(cv::countNonZero(image < 100), 0.1 * image.total());
  EXPECT_GT(cv::countNonZero(image >= 150), 0.1 * image.total());
  EXPECT_EQ(cv::countNonZero((image >= 101) & (image < 149)), 0);
  const Texture same = Texture::fromPhotos({ramp_x, ramp_y}, 1500, 700, 0.02, 9);
  const Texture other = Texture::fromPhotos({ramp_x, ramp_y}, 1500, 700, 0.02, 10);
  EXPECT_EQ(cv::norm(image, same.image(), cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(image, other.image(), cv::NORM_L1), 0.0);
}

TEST(TextureTest, ProceduralWorksFromTinyToCoarseResolutions) {
  for (const TextureStyle style : kAllStyles) {
    for (const double texel_m : {0.001, 0.05, 1.0}) {
      for (const cv::Size size : {cv::Size(1, 1), cv::Size(3, 2), cv::Size(200, 90)}) {
        const Texture texture = makeProcedural(style, 1, size.width, size.height, texel_m);
        EXPECT_EQ(texture.width(), size.width);
        EXPECT_EQ(texture.height(), size.height);
        const float value = texture.sample({0.3, 0.7}, texel_m);
        EXPECT_TRUE(value >= 0.0f && value <= 255.0f) << toString(style);
      }
    }
  }
}

TEST(TextureTest, RejectsInvalidOptions) {
  ProceduralTextureOptions options;
  options.width = 0;
  EXPECT_THROW(Texture::procedural(options), OptionError);
  options = {};
  options.height = 20000;
  EXPECT_THROW(Texture::procedural(options), OptionError);
  options = {};
  options.texel_m = 0.0;
  EXPECT_THROW(Texture::procedural(options), OptionError);
  options = {};
  options.style = static_cast<TextureStyle>(42);
  EXPECT_THROW(Texture::procedural(options), OptionError);
  EXPECT_THROW(Texture::fromImage(cv::Mat(), 0.01), OptionError);
  EXPECT_THROW(Texture::fromImage(cv::Mat(4, 4, CV_8UC1), -1.0), OptionError);
  EXPECT_THROW(Texture::fromPhotos({}, 10, 10, 0.01, 1), OptionError);
  EXPECT_THROW(Texture::fromPhotos({cv::Mat()}, 10, 10, 0.01, 1), OptionError);
  EXPECT_THROW(Texture::fromPhotos({cv::Mat(4, 4, CV_8UC1)}, 10, 0, 0.01, 1), OptionError);
}

}  // namespace
}  // namespace superdyna::sim

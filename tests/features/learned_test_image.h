#pragma once
// The seeded test image of the learned-extractor tests (learned_features_test links no simulator,
// so feature_test_util.h's procedural textures are not available there).

#include <cstdint>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace superdyna::test {

/// A seeded image with structure at several scales (random blobs, blurred), CV_8UC1.
inline cv::Mat syntheticImage(int width, int height, std::uint64_t seed) {
  cv::Mat noise(height / 4, width / 4, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::Mat image;
  cv::resize(noise, image, {width, height}, 0, 0, cv::INTER_CUBIC);
  cv::Mat fine(height, width, CV_8UC1);
  rng.fill(fine, cv::RNG::UNIFORM, 0, 40);
  return image + fine;
}

}  // namespace superdyna::test

#pragma once
// Images built from fuzzer input: a small image whose pixels the input gives, so that mutations
// change pixel values (which the parsers judge) rather than break the PNG encoding (which OpenCV
// rejects before any of our code runs). Raw inputs still fuzz the decoding path.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string_view>

namespace superdyna::fuzz {

inline constexpr int kMaxImageSide = 16;

/// The byte at `index`, 0 past the end.
inline std::uint8_t byteAt(std::string_view bytes, std::size_t index) {
  return index < bytes.size() ? static_cast<std::uint8_t>(bytes[index]) : 0;
}

/// Width and height (1..kMaxImageSide) from the first two bytes.
inline cv::Size imageSizeFrom(std::string_view bytes) {
  return {1 + byteAt(bytes, 0) % kMaxImageSide, 1 + byteAt(bytes, 1) % kMaxImageSide};
}

/// A CV_16UC1 image: the size from the first two bytes, then one little-endian uint16 a pixel.
inline cv::Mat idImageFrom(std::string_view bytes) {
  cv::Mat ids(imageSizeFrom(bytes), CV_16UC1);
  std::size_t at = 2;
  for (int r = 0; r < ids.rows; ++r) {
    for (int c = 0; c < ids.cols; ++c, at += 2)
      ids.at<std::uint16_t>(r, c) =
          static_cast<std::uint16_t>(byteAt(bytes, at) | (byteAt(bytes, at + 1) << 8));
  }
  return ids;
}

/// A CV_8UC3 image: the size from the first two bytes, then one byte a pixel choosing its colour
/// from `palette` (BGR), wrapping around.
template <std::size_t N>
cv::Mat colourImageFrom(std::string_view bytes, const cv::Vec3b (&palette)[N]) {
  cv::Mat bgr(imageSizeFrom(bytes), CV_8UC3);
  std::size_t at = 2;
  for (int r = 0; r < bgr.rows; ++r) {
    for (int c = 0; c < bgr.cols; ++c, ++at)
      bgr.at<cv::Vec3b>(r, c) = palette[byteAt(bytes, at) % N];
  }
  return bgr;
}

}  // namespace superdyna::fuzz

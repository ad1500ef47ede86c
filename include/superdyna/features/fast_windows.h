#pragma once
// FAST-9 corners of many overlapping windows of one image, as cv::FAST with non-maximum
// suppression finds them in each window, from one detection over the whole region.
//
// ORB-SLAM's extractor runs FAST on a grid of small overlapping cells (about 36x36 px). Called
// per cell, cv::FAST spends much of its time in its scalar loop (a 36 px row leaves little to its
// vector loop) and detects the 6 px overlaps twice. Here cv::FAST runs once over the region
// without suppression; each candidate is scored once, when a window first needs it, with FAST's
// corner score (the largest
// threshold at which it is still a corner, minus one: the value cv::FAST reports as response,
// whatever threshold found it); and a window's corners are those of its detection area (3 px
// inside the window) whose score beats each of its 8 neighbours that is a corner of the same
// detection area. That is cv::FAST's suppression, in which pixels outside the window or not
// corners count as score 0: the same keypoints, responses and order (row-major) as
// cv::FAST(image(window), corners, threshold, true), shifted to image coordinates
// (FastWindowsTest compares them on real and random images).

#include <array>
#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

namespace superdyna::features {

/// FAST's corner score of the pixel at `p` (row stride `step`): max over the 16 arcs of 9
/// contiguous circle pixels of the arc's smallest brightness difference to the centre, taken on
/// the brighter and on the darker side, minus one. A pixel is a FAST-9 corner at threshold t
/// exactly when its score is >= t. `p` must lie 3 px inside the image.
int fastCornerScore(const std::uint8_t* p, int step);

class FastWindows {
 public:
  /// Finds the FAST corners at `threshold` (>= 1) of `image` (CV_8UC1) within `region`; each is
  /// scored when a window first needs it. `image` must outlive this object.
  FastWindows(const cv::Mat& image, const cv::Rect& region, int threshold);

  /// Appends cv::FAST(image(window), ..., threshold, true)'s keypoints in image coordinates.
  /// Throws InputError when `window` does not lie inside the constructor's region. Not
  /// thread-safe (scores are cached).
  void detect(const cv::Rect& window, std::vector<cv::KeyPoint>& corners) const;

 private:
  static constexpr std::uint8_t kUnscored = 255;
  /// The score of the corner at (x, y) of the region, computed on first use.
  int scoreOf(int x, int y) const;

  cv::Mat roi_;  ///< The image's region.
  cv::Rect region_;
  std::array<int, 16> offsets_{};  ///< Circle pixels from the centre in roi_.
  /// CV_8UC1 over region_: a corner's score (kUnscored until first needed), 0 elsewhere.
  mutable cv::Mat scores_;
  /// The corners' columns (region coordinates), row by row in increasing order; row y's are
  /// corner_x_[row_start_[y], row_start_[y + 1]).
  std::vector<int> corner_x_;
  std::vector<std::size_t> row_start_;
};

}  // namespace superdyna::features

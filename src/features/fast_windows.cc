#include "superdyna/features/fast_windows.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/features2d.hpp>

#include "superdyna/core/error.h"

namespace superdyna::features {

namespace {

/// The Bresenham circle of radius 3 around a pixel, in circular order (dx, dy).
constexpr std::array<std::array<int, 2>, 16> kCircle = {{{0, 3},
                                                         {1, 3},
                                                         {2, 2},
                                                         {3, 1},
                                                         {3, 0},
                                                         {3, -1},
                                                         {2, -2},
                                                         {1, -3},
                                                         {0, -3},
                                                         {-1, -3},
                                                         {-2, -2},
                                                         {-3, -1},
                                                         {-3, 0},
                                                         {-3, 1},
                                                         {-2, 2},
                                                         {-1, 3}}};
constexpr std::size_t kArc = 9;  ///< FAST-9: contiguous circle pixels a corner needs.
constexpr int kRadius = 3;

/// Offsets of the circle pixels from the centre in an image of row stride `step`.
std::array<int, 16> circleOffsets(int step) {
  std::array<int, 16> offsets{};
  for (std::size_t k = 0; k < 16; ++k)
    offsets[k] = kCircle[k][1] * step + kCircle[k][0];
  return offsets;
}

int cornerScore(const std::uint8_t* p, const std::array<int, 16>& offsets) {
  // d: centre minus circle pixel, continued around the circle; for the 8 arcs starting in each
  // half of the circle at once (OpenCV's universal intrinsics), the arc's smallest and largest d.
  std::array<std::int16_t, 32> d{};
  const int v = p[0];
  for (std::size_t k = 0; k < 16; ++k)
    d[k] = static_cast<std::int16_t>(v - p[offsets[k]]);
  for (std::size_t k = 16; k < 16 + kArc - 1; ++k)
    d[k] = d[k - 16];
  cv::v_int16x8 darkest = cv::v_setall_s16(std::numeric_limits<std::int16_t>::min());
  cv::v_int16x8 brightest = cv::v_setall_s16(std::numeric_limits<std::int16_t>::max());
  for (std::size_t start = 0; start < 16; start += 8) {
    cv::v_int16x8 lowest = cv::v_load(d.data() + start), highest = lowest;
    for (std::size_t j = 1; j < kArc; ++j) {
      const cv::v_int16x8 next = cv::v_load(d.data() + start + j);
      lowest = cv::v_min(lowest, next);
      highest = cv::v_max(highest, next);
    }
    darkest = cv::v_max(darkest, lowest);
    brightest = cv::v_min(brightest, highest);
  }
  // Darker circle arc: every d > t; brighter: every -d > t.
  const int darker = cv::v_reduce_max(darkest);
  const int brighter = -cv::v_reduce_min(brightest);
  return std::max(darker, brighter) - 1;
}

}  // namespace

int fastCornerScore(const std::uint8_t* p, int step) {
  return cornerScore(p, circleOffsets(step));
}

FastWindows::FastWindows(const cv::Mat& image, const cv::Rect& region, int threshold)
    : region_(region) {
  if (image.type() != CV_8UC1 || threshold < 1 ||
      (region & cv::Rect(0, 0, image.cols, image.rows)) != region) {
    throw InputError(
        "FastWindows: expected a CV_8UC1 image, a region inside it and threshold >= 1");
  }
  roi_ = image(region);
  offsets_ = circleOffsets(static_cast<int>(roi_.step1()));
  // Not cv::Mat::zeros: its first use builds an OpenCV singleton, racing when the two images'
  // extractions start together (ThreadSanitizer).
  scores_ = cv::Mat(region.size(), CV_8UC1, cv::Scalar(0));
  std::vector<cv::KeyPoint> candidates;
  cv::FAST(roi_, candidates, threshold, false);
  std::vector<cv::Point> corners;
  corners.reserve(candidates.size());
  for (const cv::KeyPoint& c : candidates)
    corners.emplace_back(cvRound(c.pt.x), cvRound(c.pt.y));
  const auto rowMajor = [](const cv::Point& a, const cv::Point& b) {
    return a.y != b.y ? a.y < b.y : a.x < b.x;
  };
  if (!std::is_sorted(corners.begin(), corners.end(), rowMajor)) {
    std::sort(corners.begin(), corners.end(), rowMajor);  // cv::FAST reports them row-major
  }
  row_start_.assign(static_cast<std::size_t>(region.height) + 1, 0);
  corner_x_.reserve(corners.size());
  for (const cv::Point& c : corners) {
    scores_.at<std::uint8_t>(c.y, c.x) = kUnscored;
    corner_x_.push_back(c.x);
    ++row_start_[static_cast<std::size_t>(c.y) + 1];
  }
  for (std::size_t y = 1; y < row_start_.size(); ++y)
    row_start_[y] += row_start_[y - 1];
}

int FastWindows::scoreOf(int x, int y) const {
  std::uint8_t& score = scores_.at<std::uint8_t>(y, x);
  if (score == kUnscored) {
    // A corner's score is >= the threshold >= 1 and at most 254 (differences of 8-bit values).
    score = static_cast<std::uint8_t>(
        std::clamp(cornerScore(roi_.ptr<std::uint8_t>(y) + x, offsets_), 1, kUnscored - 1));
  }
  return score;
}

void FastWindows::detect(const cv::Rect& window, std::vector<cv::KeyPoint>& corners) const {
  if ((window & region_) != window) {
    throw InputError("FastWindows: a window outside the region the corners were found in");
  }
  // The window's detection area in region coordinates; outside it every score counts as 0.
  const int x0 = window.x - region_.x + kRadius;
  const int x1 = window.x - region_.x + window.width - kRadius;
  const int y0 = window.y - region_.y + kRadius;
  const int y1 = window.y - region_.y + window.height - kRadius;
  if (x1 <= x0 || y1 <= y0) return;
  const auto scoreAt = [&](int x, int y) -> int {
    if (x < x0 || x >= x1 || y < y0 || y >= y1) return 0;
    return scores_.at<std::uint8_t>(y, x) == 0 ? 0 : scoreOf(x, y);
  };
  for (int y = y0; y < y1; ++y) {
    const int* first = corner_x_.data() + row_start_[static_cast<std::size_t>(y)];
    const int* last = corner_x_.data() + row_start_[static_cast<std::size_t>(y) + 1];
    for (const int* it = std::lower_bound(first, last, x0); it != last && *it < x1; ++it) {
      const int x = *it;
      const int s = scoreOf(x, y);
      const bool strongest = s > scoreAt(x - 1, y - 1) && s > scoreAt(x, y - 1) &&
                             s > scoreAt(x + 1, y - 1) && s > scoreAt(x - 1, y) &&
                             s > scoreAt(x + 1, y) && s > scoreAt(x - 1, y + 1) &&
                             s > scoreAt(x, y + 1) && s > scoreAt(x + 1, y + 1);
      if (strongest) {
        corners.emplace_back(static_cast<float>(x + region_.x), static_cast<float>(y + region_.y),
                             7.f, -1.f, static_cast<float>(s));
      }
    }
  }
}

}  // namespace superdyna::features

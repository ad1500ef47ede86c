#include "superdyna/features/orb_extractor.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "superdyna/core/error.h"
#include "superdyna/features/fast_windows.h"
#include "superdyna/features/orb_descriptor.h"
#include "superdyna/features/quadtree.h"

namespace superdyna::features {

namespace {

/// cv::FAST examines a circle of radius 3 and never reports corners closer to the border.
constexpr int kFastRadius = 3;
/// Side of the Gaussian kernel applied before the BRIEF tests [px].
constexpr int kBlurKernel = 7;
/// Smallest edge_threshold: the orientation disc and the pattern reach kOrbPatchRadius pixels.
constexpr int kMinEdgeThreshold = kOrbPatchRadius + 1;

void requireRange(const char* name, double value, double lo, double hi) {
  if (!(value >= lo && value <= hi)) {
    throw OptionError(name, fmt::format("must be in [{}, {}], got {}", lo, hi, value));
  }
}

/// Budget per level: proportional to the level area (ratio 1 / s^2), the last level the rest.
std::vector<int> levelBudgets(int features, double scale_factor, int levels) {
  const double ratio = 1.0 / (scale_factor * scale_factor);
  const double first = features * (1.0 - ratio) / (1.0 - std::pow(ratio, levels));
  std::vector<int> targets(static_cast<std::size_t>(levels), 0);
  int assigned = 0;
  for (int l = 0; l + 1 < levels; ++l) {
    const int n =
        std::min(features - assigned, static_cast<int>(std::lround(first * std::pow(ratio, l))));
    targets[static_cast<std::size_t>(l)] = n;
    assigned += n;
  }
  targets.back() = features - assigned;
  return targets;
}

/// ORB-SLAM's FAST cells over `area` (the level minus edge_threshold - 3 px on each side): about
/// cell_size px, each widened by 3 px on every side so that the cells' corner areas (3 px inside
/// a cell) tile [edge, size - edge) without overlap; neighbouring cells overlap by 6 px.
std::vector<cv::Rect> detectionCells(const cv::Rect& area, int cell_size) {
  const int cols = std::max(1, area.width / cell_size);
  const int rows = std::max(1, area.height / cell_size);
  const int cell_w = (area.width + cols - 1) / cols, cell_h = (area.height + rows - 1) / rows;
  std::vector<cv::Rect> cells;
  for (int r = 0; r < rows; ++r) {
    const int y0 = area.y + r * cell_h;
    const int y1 = std::min(y0 + cell_h + 2 * kFastRadius, area.y + area.height);
    if (y1 - y0 <= 2 * kFastRadius) continue;
    for (int c = 0; c < cols; ++c) {
      const int x0 = area.x + c * cell_w;
      const int x1 = std::min(x0 + cell_w + 2 * kFastRadius, area.x + area.width);
      if (x1 - x0 > 2 * kFastRadius) cells.emplace_back(x0, y0, x1 - x0, y1 - y0);
    }
  }
  return cells;
}

}  // namespace

void OrbOptions::validate() const {
  requireRange("features", features, 1, 100000);
  requireRange("scale_factor", scale_factor, 1.0 + 1e-9, 2.0);
  requireRange("levels", levels, 1, 20);
  requireRange("fast_threshold", fast_threshold, 1, 254);
  requireRange("min_fast_threshold", min_fast_threshold, 1, fast_threshold);
  requireRange("cell_size", cell_size, 8, 1e6);
  requireRange("edge_threshold", edge_threshold, kMinEdgeThreshold, 1e6);
  requireRange("blur_sigma", blur_sigma, 1e-6, 100.0);
}

OrbExtractor::OrbExtractor(const OrbOptions& options) : options_(options) {
  options_.validate();
  for (int l = 0; l < options_.levels; ++l)
    scales_.push_back(std::pow(options_.scale_factor, l));
  targets_ = levelBudgets(options_.features, options_.scale_factor, options_.levels);
}

void OrbExtractor::buildPyramid(const cv::Mat& gray) {
  if (shrinkers_.empty() || shrinkers_.front().from() != gray.size()) {
    shrinkers_.clear();
    cv::Size from = gray.size();
    for (int l = 1; l < options_.levels; ++l) {
      const cv::Size to(static_cast<int>(std::lround(gray.cols / scales_[l])),
                        static_cast<int>(std::lround(gray.rows / scales_[l])));
      if (to.width < 1 || to.height < 1) break;  // deeper levels stay empty
      shrinkers_.emplace_back(from, to);
      from = to;
    }
  }
  pyramid_.assign(static_cast<std::size_t>(options_.levels), cv::Mat());
  pyramid_[0] = gray;
  for (std::size_t l = 1; l <= shrinkers_.size(); ++l)
    shrinkers_[l - 1].apply(pyramid_[l - 1], pyramid_[l]);
}

std::vector<cv::KeyPoint> OrbExtractor::detectCorners(const cv::Mat& level) const {
  const int lo = options_.edge_threshold - kFastRadius;
  const cv::Rect area(lo, lo, level.cols - 2 * lo, level.rows - 2 * lo);
  std::vector<cv::KeyPoint> corners;
  if (area.width <= 2 * kFastRadius || area.height <= 2 * kFastRadius) return corners;
  // Per cell, cv::FAST(level(cell), ..., threshold, true), read from one detection over the
  // level (fast_windows.h); a cell without corners again with the lower threshold, by cv::FAST
  // on the cell (one detection over the level at that threshold finds so many candidates in
  // textured parts that it costs more).
  const FastWindows strong(level, area, options_.fast_threshold);
  for (const cv::Rect& cell : detectionCells(area, options_.cell_size)) {
    const std::size_t before = corners.size();
    strong.detect(cell, corners);
    if (corners.size() > before || options_.min_fast_threshold >= options_.fast_threshold) {
      continue;
    }
    std::vector<cv::KeyPoint> weak;
    cv::FAST(level(cell), weak, options_.min_fast_threshold, true);
    for (cv::KeyPoint& kp : weak) {
      kp.pt.x += static_cast<float>(cell.x);
      kp.pt.y += static_cast<float>(cell.y);
      corners.push_back(kp);
    }
  }
  return corners;
}

void OrbExtractor::describeLevel(int level, const std::vector<cv::KeyPoint>& corners,
                                 const std::vector<int>& chosen, FeatureSet& features) const {
  if (chosen.empty()) return;
  const cv::Mat& image = pyramid_[static_cast<std::size_t>(level)];
  cv::Mat smoothed;
  cv::GaussianBlur(image, smoothed, cv::Size(kBlurKernel, kBlurKernel), options_.blur_sigma,
                   options_.blur_sigma, cv::BORDER_REFLECT_101);
  const double sx = static_cast<double>(pyramid_[0].cols) / image.cols;
  const double sy = static_cast<double>(pyramid_[0].rows) / image.rows;
  const float size = static_cast<float>(kOrbPatchSize * scales_[static_cast<std::size_t>(level)]);
  cv::Mat descriptors(static_cast<int>(chosen.size()), kOrbDescriptorBytes, CV_8UC1);
  for (std::size_t k = 0; k < chosen.size(); ++k) {
    const cv::KeyPoint& corner = corners[static_cast<std::size_t>(chosen[k])];
    const cv::Point at(cvRound(corner.pt.x), cvRound(corner.pt.y));
    Keypoint kp;
    kp.pixel = Eigen::Vector2d((at.x + 0.5) * sx - 0.5, (at.y + 0.5) * sy - 0.5);
    kp.angle = intensityCentroidAngle(image, at);
    kp.octave = level;
    kp.response = corner.response;
    kp.size = size;
    computeSteeredBrief(smoothed, at, kp.angle, descriptors.ptr<std::uint8_t>(static_cast<int>(k)));
    features.keypoints.push_back(kp);
  }
  features.descriptors.push_back(descriptors);
}

FeatureSet OrbExtractor::extract(const cv::Mat& gray) {
  if (gray.empty() || gray.type() != CV_8UC1) {
    throw InputError(
        fmt::format("ORB extractor: expected a non-empty CV_8UC1 image, got {}x{} "
                    "of OpenCV type {}",
                    gray.cols, gray.rows, gray.type()));
  }
  buildPyramid(gray);
  FeatureSet features;
  features.descriptor_type = DescriptorType::kBinary;
  features.image_size = gray.size();
  features.descriptors = cv::Mat(0, kOrbDescriptorBytes, CV_8UC1);
  for (int l = 0; l < options_.levels; ++l) {
    const cv::Mat& level = pyramid_[static_cast<std::size_t>(l)];
    if (level.empty()) break;
    const std::vector<cv::KeyPoint> corners = detectCorners(level);
    const int inner = options_.edge_threshold;
    const cv::Rect2f region(static_cast<float>(inner), static_cast<float>(inner),
                            static_cast<float>(level.cols - 2 * inner),
                            static_cast<float>(level.rows - 2 * inner));
    const std::vector<int> chosen =
        distributeQuadtree(corners, region, targets_[static_cast<std::size_t>(l)]);
    describeLevel(l, corners, chosen, features);
  }
  return features;
}

}  // namespace superdyna::features

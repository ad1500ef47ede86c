#include "superdyna/features/orb_extractor.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "superdyna/core/error.h"
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

/// FAST corners in one cell, with the lower threshold when the first finds none.
void detectInCell(const cv::Mat& level, const cv::Rect& cell, int threshold, int min_threshold,
                  std::vector<cv::KeyPoint>& corners) {
  std::vector<cv::KeyPoint> found;
  cv::FAST(level(cell), found, threshold, true);
  if (found.empty() && min_threshold < threshold) cv::FAST(level(cell), found, min_threshold, true);
  for (cv::KeyPoint& kp : found) {
    kp.pt.x += static_cast<float>(cell.x);
    kp.pt.y += static_cast<float>(cell.y);
    corners.push_back(kp);
  }
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
  pyramid_.assign(static_cast<std::size_t>(options_.levels), cv::Mat());
  pyramid_[0] = gray;
  for (int l = 1; l < options_.levels; ++l) {
    const cv::Size size(static_cast<int>(std::lround(gray.cols / scales_[l])),
                        static_cast<int>(std::lround(gray.rows / scales_[l])));
    if (size.width < 1 || size.height < 1) break;  // deeper levels stay empty
    cv::resize(pyramid_[l - 1], pyramid_[l], size, 0.0, 0.0, cv::INTER_AREA);
  }
}

std::vector<cv::KeyPoint> OrbExtractor::detectCorners(const cv::Mat& level) const {
  // Cells cover [edge - 3, size - edge + 3), so that corners (3 px inside a cell) land in
  // [edge, size - edge); neighbouring cells overlap by 6 px and their corner areas do not.
  const int lo = options_.edge_threshold - kFastRadius;
  const int width = level.cols - 2 * lo, height = level.rows - 2 * lo;
  std::vector<cv::KeyPoint> corners;
  if (width <= 2 * kFastRadius || height <= 2 * kFastRadius) return corners;
  const int cols = std::max(1, width / options_.cell_size);
  const int rows = std::max(1, height / options_.cell_size);
  const int cell_w = (width + cols - 1) / cols, cell_h = (height + rows - 1) / rows;
  for (int r = 0; r < rows; ++r) {
    const int y0 = lo + r * cell_h;
    const int y1 = std::min(y0 + cell_h + 2 * kFastRadius, lo + height);
    if (y1 - y0 <= 2 * kFastRadius) continue;
    for (int c = 0; c < cols; ++c) {
      const int x0 = lo + c * cell_w;
      const int x1 = std::min(x0 + cell_w + 2 * kFastRadius, lo + width);
      if (x1 - x0 <= 2 * kFastRadius) continue;
      detectInCell(level, cv::Rect(x0, y0, x1 - x0, y1 - y0), options_.fast_threshold,
                   options_.min_fast_threshold, corners);
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

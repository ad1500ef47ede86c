#include "superdyna/semantics/instance_assembly.h"

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>

namespace superdyna::semantics {

cv::Rect pixelBox(double x1, double y1, double x2, double y2, cv::Size image) {
  const auto clampTo = [](double v, int n) { return std::clamp(v, 0.0, double(n)); };
  const int x0 = static_cast<int>(std::floor(clampTo(x1, image.width)));
  const int y0 = static_cast<int>(std::floor(clampTo(y1, image.height)));
  const int x_end = static_cast<int>(std::ceil(clampTo(x2, image.width)));
  const int y_end = static_cast<int>(std::ceil(clampTo(y2, image.height)));
  return cv::Rect(x0, y0, std::max(0, x_end - x0), std::max(0, y_end - y0));
}

double sampleBilinear(const std::vector<double>& grid, int w, int h, double x, double y) {
  const double fx0 = std::floor(x), fy0 = std::floor(y);
  const double ax = x - fx0, ay = y - fy0;
  const auto clampTo = [](double v, int n) { return std::clamp(static_cast<int>(v), 0, n - 1); };
  const int x0 = clampTo(fx0, w), x1 = clampTo(fx0 + 1, w);
  const int y0 = clampTo(fy0, h), y1 = clampTo(fy0 + 1, h);
  const auto at = [&](int r, int c) {
    return grid[static_cast<std::size_t>(r) * static_cast<std::size_t>(w) +
                static_cast<std::size_t>(c)];
  };
  return (1 - ay) * ((1 - ax) * at(y0, x0) + ax * at(y0, x1)) +
         ay * ((1 - ax) * at(y1, x0) + ax * at(y1, x1));
}

InstanceAssembler::InstanceAssembler(cv::Size image, int min_area_px) : min_area_px_(min_area_px) {
  segmentation_.ids = cv::Mat(image, CV_16UC1, cv::Scalar(0));
}

bool InstanceAssembler::add(Instance instance, const cv::Mat& mask) {
  const cv::Mat taken = (mask != 0) & (segmentation_.ids == 0);
  const int area = cv::countNonZero(taken);
  if (area < min_area_px_) return false;
  instance.id = static_cast<int>(segmentation_.instances.size()) + 1;
  instance.area_px = area;
  segmentation_.ids.setTo(instance.id, taken);
  segmentation_.instances.push_back(std::move(instance));
  return true;
}

}  // namespace superdyna::semantics

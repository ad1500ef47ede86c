#pragma once
// The steps every detector backend (yolo, maskrcnn) shares once it has its detections, best score
// first, each with a mask: boxes in image pixels, bilinear sampling of a mask grid, and the
// instance-id image — each instance takes the pixels of its mask that no better-scored instance
// took, instances left with fewer than min_area pixels are dropped, the others get ids 1, 2, ...
// in that order.

#include <opencv2/core.hpp>
#include <vector>

#include "superdyna/semantics/segmenter.h"

namespace superdyna::semantics {

/// The pixels of a box given in image pixel coordinates (x2, y2 exclusive): from floor(x1, y1) to
/// ceil(x2, y2), clipped to the image (empty when it lies outside).
cv::Rect pixelBox(double x1, double y1, double x2, double y2, cv::Size image);

/// Bilinear sample of a w x h row-major grid at continuous cell coordinates (x, y) (cell centres
/// at whole numbers), clamped at the border.
double sampleBilinear(const std::vector<double>& grid, int w, int h, double x, double y);

/// Builds a Segmentation from detections added best first.
class InstanceAssembler {
 public:
  InstanceAssembler(cv::Size image, int min_area_px);

  /// Adds the next detection (`mask` CV_8UC1 of the image's size, non-zero on the instance): it
  /// gets the mask's pixels not taken yet and, when they are at least min_area_px, the next id
  /// and its area. Returns whether it was kept.
  bool add(Instance instance, const cv::Mat& mask);

  const Segmentation& segmentation() const { return segmentation_; }

 private:
  Segmentation segmentation_;
  int min_area_px_ = 1;
};

}  // namespace superdyna::semantics

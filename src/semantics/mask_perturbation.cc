#include "superdyna/semantics/mask_perturbation.h"

#include <fmt/format.h>

#include <cstdint>
#include <opencv2/imgproc.hpp>
#include <set>

namespace superdyna::semantics {

namespace {

std::set<std::uint16_t> idsIn(const cv::Mat& ids) {
  std::set<std::uint16_t> found;
  for (int r = 0; r < ids.rows; ++r) {
    const auto* row = ids.ptr<std::uint16_t>(r);
    for (int c = 0; c < ids.cols; ++c)
      if (row[c] != 0) found.insert(row[c]);
  }
  return found;
}

/// One 3x3 square dilation (grow = true) or erosion of each instance, from the same input.
void perturbOnce(cv::Mat& ids, bool grow) {
  const cv::Mat kernel = cv::Mat::ones(3, 3, CV_8UC1);
  const cv::Mat before = ids.clone();
  for (const std::uint16_t id : idsIn(before)) {
    const cv::Mat mask = before == id;
    cv::Mat changed;
    if (grow) {
      cv::dilate(mask, changed, kernel);
      // Only background pixels not yet taken by a lower id in this iteration.
      ids.setTo(id, changed & (before == 0) & (ids == 0));
    } else {
      cv::erode(mask, changed, kernel);
      ids.setTo(0, mask & ~changed);
    }
  }
}

}  // namespace

void dilateInstances(cv::Mat& ids, int iterations) {
  CV_Assert(ids.type() == CV_16UC1);
  for (int i = 0; i < iterations; ++i)
    perturbOnce(ids, true);
}

void erodeInstances(cv::Mat& ids, int iterations) {
  CV_Assert(ids.type() == CV_16UC1);
  for (int i = 0; i < iterations; ++i)
    perturbOnce(ids, false);
}

void perturbMasks(Segmentation& segmentation, int dilate_iterations, int erode_iterations) {
  if (dilate_iterations == 0 && erode_iterations == 0) return;
  segmentation.ids = segmentation.ids.clone();  // never change the backend's (cached) image
  dilateInstances(segmentation.ids, dilate_iterations);
  erodeInstances(segmentation.ids, erode_iterations);
  updateBoxesAndAreas(segmentation);
}

PerturbedSegmenter::PerturbedSegmenter(std::unique_ptr<Segmenter> segmenter, int dilate_iterations,
                                       int erode_iterations)
    : segmenter_(std::move(segmenter)), dilate_(dilate_iterations), erode_(erode_iterations) {}

Segmentation PerturbedSegmenter::segment(const cv::Mat& image, TimeNs t_ns, int camera) {
  Segmentation segmentation = segmenter_->segment(image, t_ns, camera);
  perturbMasks(segmentation, dilate_, erode_);
  return segmentation;
}

std::string PerturbedSegmenter::description() const {
  return fmt::format("{}, masks dilated {} and eroded {} times (3x3 square)",
                     segmenter_->description(), dilate_, erode_);
}

}  // namespace superdyna::semantics

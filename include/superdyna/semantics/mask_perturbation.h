#pragma once
// Mask perturbation for the paper's robustness study (its Table 11): every instance mask grown
// (dilation) or shrunk (erosion) by a number of iterations of a 3x3 kernel.
//
// The kernel is the 3x3 square (8-neighbourhood), the kernel of cv::dilate / cv::erode with a
// 3x3 cv::Mat::ones or np.ones((3, 3)) as such studies use: one iteration moves the mask border
// one pixel in every direction, diagonals included, so an axis-aligned w x h box becomes
// (w + 2) x (h + 2) when dilated and (w - 2) x (h - 2) when eroded; n iterations equal one
// (2n + 1) x (2n + 1) square. A 3x3 cross would grow a box by only 4 (w + h) pixels per iteration
// and round its corners: an anisotropic perturbation, unlike a segmenter's boundary error.
//
// Instances are perturbed one by one: a dilated instance takes only background pixels (where two
// grow into the same pixel the lower id gets it), an eroded one loses the pixels with a
// neighbour outside it (another instance or background; beyond the image border counts as
// inside, as in OpenCV). Dilation runs before erosion when both are asked for.

#include <memory>

#include "superdyna/semantics/segmenter.h"

namespace superdyna::semantics {

/// Dilates every instance of `ids` (CV_16UC1) `iterations` times with the 3x3 square.
void dilateInstances(cv::Mat& ids, int iterations);
/// Erodes every instance of `ids` (CV_16UC1) `iterations` times with the 3x3 square.
void erodeInstances(cv::Mat& ids, int iterations);

/// Dilation, then erosion, of a segmentation's masks; boxes and areas follow, instances eroded
/// away are dropped.
void perturbMasks(Segmentation& segmentation, int dilate_iterations, int erode_iterations);

/// Any segmenter with its masks perturbed.
class PerturbedSegmenter : public Segmenter {
 public:
  PerturbedSegmenter(std::unique_ptr<Segmenter> segmenter, int dilate_iterations,
                     int erode_iterations);
  Segmentation segment(const cv::Mat& image, TimeNs t_ns, int camera) override;
  std::string description() const override;
  bool idsNameObjects() const override { return segmenter_->idsNameObjects(); }

 private:
  std::unique_ptr<Segmenter> segmenter_;
  int dilate_ = 0;
  int erode_ = 0;
};

}  // namespace superdyna::semantics

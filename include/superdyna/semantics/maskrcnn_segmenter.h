#pragma once
// The maskrcnn backend: torchvision's Mask R-CNN exported to ONNX (scripts/export_maskrcnn_onnx.py)
// run through the project's ONNX Runtime wrapper and decoded as maskrcnn_decoder.h describes.
// Contract: one float input, the RGB image in [0, 1] at its own size, [3, H, W] (torchvision's
// export of a list of one image) or [1, 3, H, W]; outputs named boxes [N, 4], labels [N] (int64),
// scores [N] and masks [N, 1, h, w] (float).

#include <memory>

#include "superdyna/inference/onnx_model.h"
#include "superdyna/semantics/segmenter.h"

namespace superdyna::semantics {

class MaskRcnnSegmenter : public Segmenter {
 public:
  /// Loads the model (InputError saying where it looked when it is missing, or naming the model
  /// file and the tensor that does not fit the contract).
  MaskRcnnSegmenter(const MaskRcnnOptions& options, const Taxonomy& taxonomy);

  Segmentation segment(const cv::Mat& image, TimeNs t_ns, int camera) override;
  std::string description() const override;

  /// Mean ONNX Runtime time per image [ms].
  double meanInferenceMs() const { return model_.meanRunMs(); }

 private:
  MaskRcnnOptions options_;
  Taxonomy taxonomy_;
  inference::OnnxModel model_;
};

}  // namespace superdyna::semantics

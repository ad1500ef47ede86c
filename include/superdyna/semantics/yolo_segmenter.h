#pragma once
// The yolo backend: an Ultralytics YOLOv8-seg / YOLO11-seg ONNX export (fp32 or int8, any input
// size) run through the project's ONNX Runtime wrapper and decoded as yolo_decoder.h describes.
// Class names come from the export's "names" metadata; the taxonomy maps them to classes.

#include <memory>

#include "superdyna/inference/onnx_model.h"
#include "superdyna/semantics/segmenter.h"

namespace superdyna::semantics {

class YoloSegmenter : public Segmenter {
 public:
  /// Loads the model (InputError saying where it looked when it is missing, or naming the tensor
  /// that does not fit the YOLO-seg contract).
  YoloSegmenter(const YoloOptions& options, const Taxonomy& taxonomy);

  Segmentation segment(const cv::Mat& image, TimeNs t_ns, int camera) override;
  std::string description() const override;

  cv::Size inputSize() const { return input_; }
  const std::vector<std::string>& labels() const { return labels_; }
  /// Mean ONNX Runtime time per image [ms].
  double meanInferenceMs() const { return model_.meanRunMs(); }

 private:
  YoloOptions options_;
  Taxonomy taxonomy_;
  inference::OnnxModel model_;
  cv::Size input_;
  std::vector<std::string> labels_;
};

}  // namespace superdyna::semantics

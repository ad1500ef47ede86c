#include "superdyna/semantics/maskrcnn_segmenter.h"

#include <fmt/format.h>

#include <filesystem>

#include "superdyna/core/error.h"
#include "superdyna/inference/model_files.h"
#include "superdyna/semantics/maskrcnn_decoder.h"
#include "superdyna/semantics/yolo_decoder.h"

namespace superdyna::semantics {

namespace {

/// The contract with an image input of rank 3 ([3, H, W]) or 4 ([1, 3, H, W]).
inference::ModelSignature maskRcnnSignature(bool batched) {
  using inference::DimSpec;
  inference::ModelSignature signature;
  signature.network = "torchvision Mask R-CNN";
  std::vector<DimSpec> image = {DimSpec::fixed(3, "channels"), DimSpec::dynamic("height"),
                                DimSpec::dynamic("width")};
  if (batched) image.insert(image.begin(), DimSpec::fixed(1, "batch"));
  signature.inputs.push_back({"", image, inference::ElementType::kFloat32});
  const DimSpec n = DimSpec::dynamic("detections");
  signature.outputs.push_back(
      {"boxes", {n, DimSpec::fixed(4, "x1 y1 x2 y2")}, inference::ElementType::kFloat32});
  signature.outputs.push_back({"labels", {n}, inference::ElementType::kInt64});
  signature.outputs.push_back({"scores", {n}, inference::ElementType::kFloat32});
  signature.outputs.push_back({"masks",
                               {n, DimSpec::fixed(1, "channels"), DimSpec::dynamic("mask height"),
                                DimSpec::dynamic("mask width")},
                               inference::ElementType::kFloat32});
  return signature;
}

inference::OnnxModel loadModel(const MaskRcnnOptions& options) {
  options.validate();
  inference::OnnxModelOptions runtime;
  runtime.intra_op_threads = options.inference_threads;
  const std::filesystem::path file = inference::findModel(
      options.model,
      "Mask R-CNN models: export torchvision's maskrcnn_resnet50_fpn with "
      "scripts/export_maskrcnn_onnx.py OUT.onnx (semantics.maskrcnn_model; docs/concepts/"
      "segmentation.md).");
  return inference::OnnxModel(file, {maskRcnnSignature(false), maskRcnnSignature(true)}, runtime);
}

}  // namespace

MaskRcnnSegmenter::MaskRcnnSegmenter(const MaskRcnnOptions& options, const Taxonomy& taxonomy)
    : options_(options), taxonomy_(taxonomy), model_(loadModel(options)) {}

Segmentation MaskRcnnSegmenter::segment(const cv::Mat& image, TimeNs /*t_ns*/, int /*camera*/) {
  // The network takes the image at its own size: an identity letterbox.
  const std::vector<float> input =
      letterboxedInput(image, letterboxFor(image.size(), image.size()));
  std::vector<std::int64_t> shape = {3, image.rows, image.cols};
  if (model_.signature().inputs.front().dims.size() == 4) shape.insert(shape.begin(), 1);
  const std::vector<inference::Tensor> outputs = model_.run({{input.data(), shape}});
  const inference::Tensor& masks = outputs[3];
  MaskRcnnOutputs view;
  view.detections = static_cast<int>(outputs[0].dim(0));
  view.boxes = outputs[0].data.data();
  view.labels = outputs[1].data.data();
  view.scores = outputs[2].data.data();
  view.masks = masks.data.data();
  view.mask_h = static_cast<int>(masks.dim(2));
  view.mask_w = static_cast<int>(masks.dim(3));
  if (outputs[1].dim(0) != view.detections || outputs[2].dim(0) != view.detections ||
      masks.dim(0) != view.detections) {
    throw InputError(
        InputLocation{model_.file()},
        fmt::format("outputs disagree on the detection count: boxes {}, labels {}, "
                    "scores {}, masks {}",
                    view.detections, outputs[1].dim(0), outputs[2].dim(0), masks.dim(0)));
  }
  try {
    return decodeMaskRcnn(view, image.size(), taxonomy_, options_);
  } catch (const InputError& e) {
    throw InputError(InputLocation{model_.file()}, e.what());
  }
}

std::string MaskRcnnSegmenter::description() const {
  return fmt::format("maskrcnn ({})", model_.file().filename().string());
}

}  // namespace superdyna::semantics

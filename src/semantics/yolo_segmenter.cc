#include "superdyna/semantics/yolo_segmenter.h"

#include <fmt/format.h>

#include <filesystem>

#include "superdyna/core/error.h"
#include "superdyna/inference/model_files.h"
#include "superdyna/semantics/yolo_decoder.h"

namespace superdyna::semantics {

namespace {

constexpr int kSizeMultiple = 32;  // YOLO's largest stride.

inference::ModelSignature yoloSignature() {
  using inference::DimSpec;
  inference::ModelSignature signature;
  signature.network = "YOLOv8-seg";
  signature.inputs.push_back(
      {"",
       {DimSpec::fixed(1, "batch"), DimSpec::fixed(3, "channels"),
        DimSpec::multipleOf(kSizeMultiple, "height"), DimSpec::multipleOf(kSizeMultiple, "width")},
       inference::ElementType::kFloat32});
  signature.outputs.push_back({"output0",
                               {DimSpec::fixed(1, "batch"), DimSpec::dynamic("4 + classes + masks"),
                                DimSpec::dynamic("anchors")},
                               inference::ElementType::kFloat32});
  signature.outputs.push_back({"output1",
                               {DimSpec::fixed(1, "batch"), DimSpec::dynamic("masks"),
                                DimSpec::dynamic("height / 4"), DimSpec::dynamic("width / 4")},
                               inference::ElementType::kFloat32});
  return signature;
}

inference::OnnxModel loadModel(const YoloOptions& options) {
  options.validate();
  inference::OnnxModelOptions runtime;
  runtime.intra_op_threads = options.inference_threads;
  const std::filesystem::path file = inference::findModel(
      options.model,
      "YOLOv8-seg models: export one with Ultralytics (yolo export "
      "model=yolov8n-seg.pt format=onnx), or use ../shared/models/"
      "yolov8n-seg-int8.onnx beside the checkout (semantics.yolo_model; docs/concepts/"
      "segmentation.md).");
  return inference::OnnxModel(file, yoloSignature(), runtime);
}

/// The model's input size: its fixed sides, or input_size for a dynamic model.
cv::Size inputSizeOf(const inference::OnnxModel& model, int input_size) {
  const std::vector<std::int64_t>& dims = model.modelInputs().front().dims;
  const bool fixed = dims.size() == 4 && dims[2] > 0 && dims[3] > 0;
  if (fixed) {
    const cv::Size size(static_cast<int>(dims[3]), static_cast<int>(dims[2]));
    if (input_size != 0 && (size.width != input_size || size.height != input_size)) {
      throw InputError(InputLocation{model.file()},
                       fmt::format("the model's input is fixed at {}x{}; semantics.yolo_input_size "
                                   "{} needs a model exported at that size (or 0)",
                                   size.width, size.height, input_size));
    }
    return size;
  }
  if (input_size == 0) {
    throw InputError(InputLocation{model.file()},
                     "the model's input size is dynamic: set semantics.yolo_input_size");
  }
  return cv::Size(input_size, input_size);
}

}  // namespace

YoloSegmenter::YoloSegmenter(const YoloOptions& options, const Taxonomy& taxonomy)
    : options_(options),
      taxonomy_(taxonomy),
      model_(loadModel(options)),
      input_(inputSizeOf(model_, options.input_size)) {
  labels_ = parseUltralyticsNames(model_.metadata("names").value_or(""));
  if (labels_.empty()) {
    throw InputError(InputLocation{model_.file()},
                     "the model has no Ultralytics 'names' metadata naming its classes");
  }
  model_.warmUp({{1, 3, input_.height, input_.width}});
}

Segmentation YoloSegmenter::segment(const cv::Mat& image, TimeNs /*t_ns*/, int /*camera*/) {
  const Letterbox letterbox = letterboxFor(image.size(), input_);
  const std::vector<float> input = letterboxedInput(image, letterbox);
  const std::vector<inference::Tensor> outputs =
      model_.run({{input.data(), {1, 3, input_.height, input_.width}}});
  const inference::Tensor& output0 = outputs[0];
  const inference::Tensor& protos = outputs[1];
  YoloOutputs view;
  view.output0 = output0.data.data();
  view.channels = static_cast<int>(output0.dim(1));
  view.anchors = static_cast<int>(output0.dim(2));
  view.protos = protos.data.data();
  view.masks = static_cast<int>(protos.dim(1));
  view.proto_h = static_cast<int>(protos.dim(2));
  view.proto_w = static_cast<int>(protos.dim(3));
  try {
    return decodeSegmentation(view, letterbox, image.size(), labels_, taxonomy_, options_);
  } catch (const InputError& e) {
    throw InputError(InputLocation{model_.file()}, e.what());
  }
}

std::string YoloSegmenter::description() const {
  return fmt::format("yolo ({}, {}x{} input)", model_.file().filename().string(), input_.width,
                     input_.height);
}

}  // namespace superdyna::semantics

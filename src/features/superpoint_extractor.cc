#include "superdyna/features/superpoint_extractor.h"

#include <fmt/format.h>

#include <chrono>
#include <numeric>

#include "dense_output.h"
#include "superdyna/core/error.h"
#include "superdyna/inference/model_files.h"

namespace superdyna::features {

namespace {

constexpr int kStride = 8;

inference::OnnxModel loadModel(const SuperPointOptions& options) {
  options.validate();
  return inference::OnnxModel(inference::findModel(options.model),
                              SuperPointExtractor::signature(options), options.runtime);
}

/// The options' multiple, raised to a multiple of the model's metadata value when it has one.
int effectiveSizeMultiple(const SuperPointOptions& options, const inference::OnnxModel& model) {
  const auto value = model.metadata(SuperPointExtractor::kSizeMultipleKey);
  if (!value) return options.size_multiple;
  int required = 0;
  try {
    required = std::stoi(*value);
  } catch (const std::exception&) {
    required = 0;
  }
  if (required < 1 || required > 1024) {
    throw InputError(
        InputLocation(model.file(), 0, SuperPointExtractor::kSizeMultipleKey),
        fmt::format("metadata value '{}' is not a size multiple in [1, 1024]", *value));
  }
  return std::lcm(options.size_multiple, required);
}

/// 1 or 3, the model input's channel dimension (a dynamic one is taken as 1, gray); InputError
/// naming the model file and input otherwise.
int inputChannelsOf(const inference::OnnxModel& model) {
  const inference::TensorInfo& input = model.modelInputs().at(0);
  const std::int64_t channels = input.dims.size() == 4 ? input.dims[1] : 0;
  if (channels < 0) return 1;
  if (channels != 1 && channels != 3) {
    throw InputError(InputLocation(model.file(), 0, input.name),
                     fmt::format("SuperPoint input {} has {} channels; expected 1 (gray) or 3 "
                                 "(RGB)",
                                 input.describe(), channels));
  }
  return static_cast<int>(channels);
}

}  // namespace

void SuperPointOptions::validate() const {
  if (model.empty()) throw OptionError("model", "must name a model file");
  if (max_keypoints < 1) {
    throw OptionError("max_keypoints", fmt::format("must be >= 1, got {}", max_keypoints));
  }
  if (!(confidence_threshold >= 0.0f && confidence_threshold < 1.0f)) {
    throw OptionError("confidence_threshold",
                      fmt::format("must be in [0, 1), got {}", confidence_threshold));
  }
  if (nms_radius < 0)
    throw OptionError("nms_radius", fmt::format("must be >= 0, got {}", nms_radius));
  if (border < 0) throw OptionError("border", fmt::format("must be >= 0, got {}", border));
  if (grid_cell_px < 0) {
    throw OptionError("grid_cell_px", fmt::format("must be >= 0, got {}", grid_cell_px));
  }
  checkInputScale(input_scale);
  if (size_multiple < kStride || size_multiple % kStride != 0) {
    throw OptionError("size_multiple", fmt::format("must be a positive multiple of {}, got {}",
                                                   kStride, size_multiple));
  }
  if (warmup_size.width < 0 || warmup_size.height < 0) {
    throw OptionError("warmup_size", "must not be negative");
  }
  if (scores_output.empty() || descriptors_output.empty()) {
    throw OptionError("scores_output/descriptors_output", "output names must not be empty");
  }
  runtime.validate();
}

inference::ModelSignature SuperPointExtractor::signature(const SuperPointOptions& options) {
  using inference::DimSpec;
  inference::ModelSignature signature;
  signature.network = "SuperPoint";
  signature.inputs.push_back(
      {"",
       {DimSpec::dynamic("batch"), DimSpec::dynamic("channels: 1 or 3"),
        DimSpec::multipleOf(kStride, "height"), DimSpec::multipleOf(kStride, "width")},
       inference::ElementType::kFloat32});
  signature.outputs.push_back({options.scores_output,
                               {DimSpec::dynamic("batch"), DimSpec::fixed(65, "channels"),
                                DimSpec::dynamic("height / 8"), DimSpec::dynamic("width / 8")},
                               inference::ElementType::kFloat32});
  signature.outputs.push_back({options.descriptors_output,
                               {DimSpec::dynamic("batch"), DimSpec::dynamic("descriptor size"),
                                DimSpec::dynamic("height / 8"), DimSpec::dynamic("width / 8")},
                               inference::ElementType::kFloat32});
  return signature;
}

SuperPointExtractor::SuperPointExtractor(const SuperPointOptions& options)
    : options_(options), model_(loadModel(options)) {
  size_multiple_ = effectiveSizeMultiple(options_, model_);
  input_channels_ = inputChannelsOf(model_);
  if (!options_.warmup_size.empty()) {
    const auto fit =
        planFit(options_.warmup_size, size_multiple_, options_.fit, options_.input_scale);
    model_.warmUp({{1, input_channels_, fit.network.height, fit.network.width}});
  }
}

FeatureSet SuperPointExtractor::extract(const cv::Mat& gray) {
  if (gray.empty() || gray.type() != CV_8UC1) {
    throw InputError("SuperPoint needs a non-empty 8-bit grayscale image (CV_8UC1)");
  }
  const auto start = std::chrono::steady_clock::now();
  const ImageFit fit = planFit(gray.size(), size_multiple_, options_.fit, options_.input_scale);
  const cv::Mat fitted = applyFit(gray, fit);

  const int H = fit.network.height, W = fit.network.width;
  grayToNetworkInput(fitted, input_channels_, input_);
  const auto outputs = model_.runInPlace({{input_.data(), {1, input_channels_, H, W}}});
  const DenseMap semi =
      denseOutputMap(outputs[0], options_.scores_output, fit.network, model_.file(), kStride);
  const DenseMap desc =
      denseOutputMap(outputs[1], options_.descriptors_output, fit.network, model_.file(), kStride);
  if (desc.channels < 1) {
    throw InputError(InputLocation(model_.file()),
                     fmt::format("output '{}' has no channels", options_.descriptors_output));
  }

  const cv::Mat heatmap = cellLogitsToHeatmap(semi, kStride)(cv::Rect({0, 0}, fit.valid()));
  std::vector<ScoredPixel> points = pixelsAtLeast(heatmap, options_.confidence_threshold);
  points = suppressNonMaxima(std::move(points), options_.nms_radius, heatmap.size());
  points = keepInside(points, options_.border, heatmap.size());
  points = selectTopK(std::move(points), options_.max_keypoints, options_.grid_cell_px);

  FeatureSet features = scoredPixelsToFeatures(points, desc, fit, gray.size(), kStride);
  last_extract_ms_ =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return features;
}

}  // namespace superdyna::features

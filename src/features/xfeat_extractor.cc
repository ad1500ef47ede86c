#include "superdyna/features/xfeat_extractor.h"

#include <fmt/format.h>

#include <chrono>

#include "dense_output.h"
#include "superdyna/core/error.h"
#include "superdyna/inference/model_files.h"

namespace superdyna::features {

namespace {

constexpr int kStride = 8;         // Cell side of the network's 1/8 maps.
constexpr int kSizeMultiple = 32;  // XFeat's input sides must be multiples of 32.
constexpr int kDescriptorSize = 64;

inference::OnnxModel loadModel(const XFeatOptions& options) {
  options.validate();
  return inference::OnnxModel(inference::findModel(options.model),
                              XFeatExtractor::signature(options), options.runtime);
}

}  // namespace

void XFeatOptions::validate() const {
  if (model.empty()) throw OptionError("model", "must name a model file");
  if (max_keypoints < 1) {
    throw OptionError("max_keypoints", fmt::format("must be >= 1, got {}", max_keypoints));
  }
  if (!(detection_threshold >= 0.0f && detection_threshold < 1.0f)) {
    throw OptionError("detection_threshold",
                      fmt::format("must be in [0, 1), got {}", detection_threshold));
  }
  if (nms_window < 1 || nms_window % 2 == 0) {
    throw OptionError("nms_window", fmt::format("must be odd and >= 1, got {}", nms_window));
  }
  if (subpixel_radius < 0) {
    throw OptionError("subpixel_radius", fmt::format("must be >= 0, got {}", subpixel_radius));
  }
  if (grid_cell_px < 0) {
    throw OptionError("grid_cell_px", fmt::format("must be >= 0, got {}", grid_cell_px));
  }
  checkInputScale(input_scale);
  if (warmup_size.width < 0 || warmup_size.height < 0) {
    throw OptionError("warmup_size", "must not be negative");
  }
  if (descriptors_output.empty() || keypoints_output.empty() || reliability_output.empty()) {
    throw OptionError("descriptors_output/keypoints_output/reliability_output",
                      "output names must not be empty");
  }
  runtime.validate();
}

inference::ModelSignature XFeatExtractor::signature(const XFeatOptions& options) {
  using inference::DimSpec;
  inference::ModelSignature signature;
  signature.network = "XFeat";
  signature.inputs.push_back(
      {"",
       {DimSpec::dynamic("batch"), DimSpec::fixed(3, "channels"),
        DimSpec::multipleOf(kSizeMultiple, "height"), DimSpec::multipleOf(kSizeMultiple, "width")},
       inference::ElementType::kFloat32});
  const auto map = [](const std::string& name, std::int64_t channels) {
    return inference::TensorSpec{name,
                                 {DimSpec::dynamic("batch"), DimSpec::fixed(channels, "channels"),
                                  DimSpec::dynamic("height / 8"), DimSpec::dynamic("width / 8")},
                                 inference::ElementType::kFloat32};
  };
  signature.outputs.push_back(map(options.descriptors_output, kDescriptorSize));
  signature.outputs.push_back(map(options.keypoints_output, kStride * kStride + 1));
  signature.outputs.push_back(map(options.reliability_output, 1));
  return signature;
}

XFeatExtractor::XFeatExtractor(const XFeatOptions& options)
    : options_(options), model_(loadModel(options)) {
  if (!options_.warmup_size.empty()) {
    const auto fit =
        planFit(options_.warmup_size, kSizeMultiple, options_.fit, options_.input_scale);
    model_.warmUp({{1, 3, fit.network.height, fit.network.width}});
  }
}

FeatureSet XFeatExtractor::extract(const cv::Mat& gray) {
  if (gray.empty() || gray.type() != CV_8UC1) {
    throw InputError("XFeat needs a non-empty 8-bit grayscale image (CV_8UC1)");
  }
  const auto start = std::chrono::steady_clock::now();
  const ImageFit fit = planFit(gray.size(), kSizeMultiple, options_.fit, options_.input_scale);
  const cv::Mat fitted = applyFit(gray, fit);

  // [1, 3, H, W]: the gray image in all three channels (the network averages them).
  const int H = fit.network.height, W = fit.network.width;
  grayToNetworkInput(fitted, 3, input_);
  const auto outputs = model_.runInPlace({{input_.data(), {1, 3, H, W}}});
  const DenseMap descriptors =
      denseOutputMap(outputs[0], options_.descriptors_output, fit.network, model_.file(), kStride);
  const DenseMap logits =
      denseOutputMap(outputs[1], options_.keypoints_output, fit.network, model_.file(), kStride);
  const DenseMap reliability =
      denseOutputMap(outputs[2], options_.reliability_output, fit.network, model_.file(), kStride);

  // Detection on the part of the heatmap that shows the image (not the padding).
  // Cells that cannot reach the detection threshold are skipped (same maxima, same scores).
  const cv::Mat heatmap = cellLogitsToHeatmap(
      logits, kStride, options_.detection_threshold)(cv::Rect({0, 0}, fit.valid()));
  std::vector<ScoredPixel> points =
      localMaxima(heatmap, options_.nms_window, options_.detection_threshold);
  for (auto& p : points) {
    const Eigen::Vector2d uv = pixelToMap(Eigen::Vector2d(p.x, p.y), kStride);
    p.score *= sampleBilinear(reliability, 0, uv.x(), uv.y());
  }
  points = selectTopK(std::move(points), options_.max_keypoints, options_.grid_cell_px);

  const std::vector<float> unit_cells = normalizeCells(descriptors);
  const DenseMap unit_map{unit_cells.data(), descriptors.channels, descriptors.rows,
                          descriptors.cols};

  FeatureSet features =
      scoredPixelsToFeatures(points, refineSubpixel(heatmap, points, options_.subpixel_radius),
                             unit_map, fit, gray.size(), kStride);
  last_extract_ms_ =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return features;
}

}  // namespace superdyna::features

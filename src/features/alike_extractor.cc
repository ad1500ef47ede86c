#include "superdyna/features/alike_extractor.h"

#include <fmt/format.h>

#include <chrono>

#include "dense_output.h"
#include "superdyna/core/error.h"
#include "superdyna/inference/model_files.h"

namespace superdyna::features {

namespace {

constexpr int kStride = 1;         // Both maps are at full resolution.
constexpr int kSizeMultiple = 32;  // ALIKE's input sides must be multiples of 32.

inference::OnnxModel loadModel(const AlikeOptions& options) {
  options.validate();
  return inference::OnnxModel(inference::findModel(options.model),
                              AlikeExtractor::signature(options), options.runtime);
}

}  // namespace

void AlikeOptions::validate() const {
  if (model.empty()) throw OptionError("model", "must name a model file");
  if (max_keypoints < 1) {
    throw OptionError("max_keypoints", fmt::format("must be >= 1, got {}", max_keypoints));
  }
  if (!(score_threshold >= 0.0f && score_threshold < 1.0f)) {
    throw OptionError("score_threshold", fmt::format("must be in [0, 1), got {}", score_threshold));
  }
  if (radius < 1) throw OptionError("radius", fmt::format("must be >= 1, got {}", radius));
  if (!(temperature > 0.0f)) {
    throw OptionError("temperature", fmt::format("must be > 0, got {}", temperature));
  }
  if (grid_cell_px < 0) {
    throw OptionError("grid_cell_px", fmt::format("must be >= 0, got {}", grid_cell_px));
  }
  checkInputScale(input_scale);
  if (warmup_size.width < 0 || warmup_size.height < 0) {
    throw OptionError("warmup_size", "must not be negative");
  }
  if (scores_output.empty() || descriptors_output.empty()) {
    throw OptionError("scores_output/descriptors_output", "output names must not be empty");
  }
  runtime.validate();
}

inference::ModelSignature AlikeExtractor::signature(const AlikeOptions& options) {
  using inference::DimSpec;
  inference::ModelSignature signature;
  signature.network = "ALIKE";
  signature.inputs.push_back(
      {"",
       {DimSpec::dynamic("batch"), DimSpec::fixed(3, "channels"),
        DimSpec::multipleOf(kSizeMultiple, "height"), DimSpec::multipleOf(kSizeMultiple, "width")},
       inference::ElementType::kFloat32});
  signature.outputs.push_back({options.scores_output,
                               {DimSpec::dynamic("batch"), DimSpec::fixed(1, "channels"),
                                DimSpec::dynamic("height"), DimSpec::dynamic("width")},
                               inference::ElementType::kFloat32});
  signature.outputs.push_back({options.descriptors_output,
                               {DimSpec::dynamic("batch"), DimSpec::dynamic("descriptor size"),
                                DimSpec::dynamic("height"), DimSpec::dynamic("width")},
                               inference::ElementType::kFloat32});
  return signature;
}

AlikeExtractor::AlikeExtractor(const AlikeOptions& options)
    : options_(options), model_(loadModel(options)) {
  if (!options_.warmup_size.empty()) {
    const auto fit =
        planFit(options_.warmup_size, kSizeMultiple, options_.fit, options_.input_scale);
    model_.warmUp({{1, 3, fit.network.height, fit.network.width}});
  }
}

FeatureSet AlikeExtractor::extract(const cv::Mat& gray) {
  if (gray.empty() || gray.type() != CV_8UC1) {
    throw InputError("ALIKE needs a non-empty 8-bit grayscale image (CV_8UC1)");
  }
  const auto start = std::chrono::steady_clock::now();
  const ImageFit fit = planFit(gray.size(), kSizeMultiple, options_.fit, options_.input_scale);
  const cv::Mat fitted = applyFit(gray, fit);

  // [1, 3, H, W]: the gray image in all three channels.
  const int H = fit.network.height, W = fit.network.width;
  grayToNetworkInput(fitted, 3, input_);
  const auto outputs = model_.runInPlace({{input_.data(), {1, 3, H, W}}});
  const DenseMap scores =
      denseOutputMap(outputs[0], options_.scores_output, fit.network, model_.file(), kStride);
  const DenseMap descriptors =
      denseOutputMap(outputs[1], options_.descriptors_output, fit.network, model_.file(), kStride);
  if (descriptors.channels < 1) {
    throw InputError(InputLocation(model_.file()),
                     fmt::format("output '{}' has no channels", options_.descriptors_output));
  }

  // Detection on the part of the score map that shows the image (not the padding).
  const cv::Mat full(scores.rows, scores.cols, CV_32FC1, const_cast<float*>(scores.data));
  const cv::Mat score_map = full(cv::Rect({0, 0}, fit.valid()));
  std::vector<ScoredPixel> points =
      localMaxima(score_map, 2 * options_.radius + 1, options_.score_threshold);
  points = keepInside(points, options_.radius + 1, score_map.size());
  points = selectTopK(std::move(points), options_.max_keypoints, options_.grid_cell_px);
  const std::vector<Eigen::Vector2d> refined =
      refineSoftArgmax(score_map, points, options_.radius, options_.temperature);
  for (std::size_t i = 0; i < points.size(); ++i)
    points[i].score = sampleBilinear(scores, 0, refined[i].x(), refined[i].y());

  FeatureSet features =
      scoredPixelsToFeatures(points, refined, descriptors, fit, gray.size(), kStride);
  last_extract_ms_ =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return features;
}

}  // namespace superdyna::features

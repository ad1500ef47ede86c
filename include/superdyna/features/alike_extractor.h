#pragma once
// ALIKE keypoints and descriptors (Zhao et al., "ALIKE: Accurate and Lightweight Keypoint
// Detection and Descriptor Extraction", IEEE TMM 2022) from the authors' networks exported to ONNX
// (alike-{t,s,n,l}.onnx: input [1,3,H,W] RGB in [0,1], H and W multiples of 32; outputs
// `scores_map` [1,1,H,W] (sigmoid) and `descriptor_map` [1,D,H,W], both at full resolution,
// D = 64 / 96 / 128 / 128 for t / s / n / l).
//
// extract() decodes the outputs as the authors' DKD (differentiable keypoint detection) does:
//  1. the gray image in all three channels, scaled to [0,1], padded (or resized) to multiples
//     of 32 (keypoint_decoding.h: ImageFit);
//  2. non-maximum suppression: pixels equal to the maximum of their (2r+1)^2 window (r = radius,
//     2) with a score above the threshold; the authors' simple_nms adds, in two more passes,
//     maxima next to suppressed windows: left out (they are the weakest candidates);
//  3. keypoints within r+1 pixels of the image border dropped;
//  4. the top-K scores (1200), optionally spread over a grid of cells;
//  5. sub-pixel position: the soft-argmax of the (2r+1)^2 score window around each maximum,
//     weights exp((s - max) / temperature), temperature 0.1 (keypoint_decoding.h:
//     refineSoftArgmax); the score sampled bilinearly there is the keypoint's response;
//  6. descriptors: the full-resolution map sampled bilinearly at the sub-pixel keypoints (pixel
//     centres, the authors' grid_sample with align_corners=True), L2-normalised.
// Keypoints carry the score as response, no angle (-1), octave 0 and size 1 (one pixel).

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "superdyna/features/feature_set.h"
#include "superdyna/features/keypoint_decoding.h"
#include "superdyna/inference/onnx_model.h"

namespace superdyna::features {

struct AlikeOptions {
  /// Model file (inference::findModel() for a bare name, else the path as given); the variant is
  /// chosen by file: alike-t.onnx (fastest) ... alike-l.onnx.
  std::string model = "alike-t.onnx";
  int max_keypoints = 1200;      ///< Top-K, >= 1.
  float score_threshold = 0.2f;  ///< Score a local maximum must exceed, in [0, 1).
  int radius = 2;                ///< NMS and soft-argmax window radius [px], >= 1.
  float temperature = 0.1f;      ///< Soft-argmax temperature, > 0.
  int grid_cell_px = 0;          ///< Spread the top-K over cells of this side [px]; 0: off.
  FitMode fit = FitMode::kPad;   ///< How images are brought to multiples of 32.
  /// The image is scaled by this factor, in (0, 1], before the network sees it (keypoints are
  /// returned in the original image's pixels): fewer pixels, a faster network.
  double input_scale = 1.0;
  cv::Size warmup_size;  ///< Warm-up image size at construction (empty: none).
  /// Output names (the input is taken by position).
  std::string scores_output = "scores_map";
  std::string descriptors_output = "descriptor_map";
  inference::OnnxModelOptions runtime;

  /// Throws OptionError naming the first invalid field.
  void validate() const;
};

/// ALIKE extractor; see the file comment. Deterministic for a given thread count.
class AlikeExtractor final : public FeatureExtractor {
 public:
  /// Loads the model and checks its contract (input [any,3,32k,32k] float; `scores_map` with one
  /// channel, `descriptor_map` of rank 4): InputError naming the model file and tensor otherwise.
  explicit AlikeExtractor(const AlikeOptions& options = {});

  /// Keypoints in the top-K order of their integer-pixel scores (the response is the score at
  /// the sub-pixel position); descriptors CV_32FC1 of unit norm (D floats);
  /// DescriptorType::kFloat. Throws InputError unless `gray` is a non-empty CV_8UC1 image.
  FeatureSet extract(const cv::Mat& gray) override;
  std::string name() const override { return "alike"; }

  const AlikeOptions& options() const { return options_; }
  const inference::OnnxModel& model() const { return model_; }
  double lastExtractMs() const { return last_extract_ms_; }
  double lastInferenceMs() const { return model_.lastRunMs(); }

  static inference::ModelSignature signature(const AlikeOptions& options);

 private:
  AlikeOptions options_;
  inference::OnnxModel model_;
  std::vector<float> input_;
  double last_extract_ms_ = 0.0;
};

}  // namespace superdyna::features

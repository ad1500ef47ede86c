#pragma once
// XFeat keypoints and descriptors (Potje et al., "XFeat: Accelerated Features for Lightweight
// Image Matching", CVPR 2024) from the authors' network exported to ONNX (xfeat.onnx: input
// [B,3,H,W] RGB in [0,1], H and W multiples of 32; outputs `descriptors` [B,64,H/8,W/8],
// `keypoint_logits` [B,65,H/8,W/8], `reliability` [B,1,H/8,W/8]).
//
// extract() decodes the outputs as the authors' detectAndCompute() does:
//  1. the gray image, replicated into three channels and scaled to [0,1], padded (or resized) to
//     multiples of 32 (keypoint_decoding.h: ImageFit);
//  2. heatmap = depth-to-space(softmax over the 65 logits, dustbin dropped), full resolution;
//  3. non-maximum suppression: pixels equal to the maximum of their 5x5 window with heat > 0.05
//     (inside the image: padding never yields keypoints);
//  4. score = heat x reliability, the reliability map sampled bilinearly at the keypoint;
//     with subpixel_radius > 0 (not in the authors' code) the chosen maxima then move to the
//     heat-weighted centroid of their window: integer maxima of blurred or dim images land 1-3 px
//     off (bench/match_accuracy.cc measures it) and sub-pixel positions match better;
//  5. the top-K scores (1200), optionally spread over a grid of cells;
//  6. descriptors: the dense 64-d map L2-normalised per cell, sampled bilinearly at the
//     keypoints, L2-normalised again.
// Map coordinates follow the pixel-centre convention of keypoint_decoding.h (the authors' differ
// by at most 1/16 cell); with FitMode::kResize keypoints are mapped back centre to centre.
// Keypoints carry the score as response, no angle (-1), octave 0 and size 8 (one cell).

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "superdyna/features/feature_set.h"
#include "superdyna/features/keypoint_decoding.h"
#include "superdyna/inference/onnx_model.h"

namespace superdyna::features {

struct XFeatOptions {
  /// Model file: a bare name is looked up by inference::findModel() ($SUPERDYNA_MODEL_DIR, then
  /// the repository's models/); a path is used as given.
  std::string model = "xfeat.onnx";
  int max_keypoints = 1200;           ///< Top-K, >= 1.
  float detection_threshold = 0.05f;  ///< Heat a local maximum must exceed, in [0, 1).
  int nms_window = 5;                 ///< Side of the max-pool window [px], odd, >= 1.
  /// Spread the top-K over square cells of this side [px] (keypoint_decoding.h: selectTopK);
  /// 0 takes the K best scores wherever they are.
  int grid_cell_px = 0;
  /// Sub-pixel keypoints: heat-weighted centroid of the (2r+1)^2 heatmap window around each
  /// maximum (keypoint_decoding.h: refineSubpixel), >= 0; 0 keeps the integer pixels.
  int subpixel_radius = 0;
  FitMode fit = FitMode::kPad;  ///< How images are brought to multiples of 32.
  /// The image is scaled by this factor, in (0, 1], before the network sees it (keypoints are
  /// returned in the original image's pixels): fewer pixels, a faster network.
  double input_scale = 1.0;
  /// Warm the network up for images of this size at construction (empty: no warm-up).
  cv::Size warmup_size;
  /// Tensor names: the input is taken by position; outputs by these names (other exports of the
  /// same network name them differently).
  std::string descriptors_output = "descriptors";
  std::string keypoints_output = "keypoint_logits";
  std::string reliability_output = "reliability";
  inference::OnnxModelOptions runtime;  ///< Threads (2), graph optimisation (all).

  /// Throws OptionError naming the first invalid field.
  void validate() const;
};

/// XFeat extractor; see the file comment. Deterministic for a given thread count.
class XFeatExtractor final : public FeatureExtractor {
 public:
  /// Loads the model and checks its contract (input [any,3,32k,32k] float; the three outputs
  /// with 64, 65 and 1 channels): InputError naming the model file and the tensor otherwise.
  explicit XFeatExtractor(const XFeatOptions& options = {});

  /// Keypoints sorted by decreasing score; descriptors CV_32FC1, 64 floats of unit norm per row;
  /// DescriptorType::kFloat. Throws InputError unless `gray` is a non-empty CV_8UC1 image.
  FeatureSet extract(const cv::Mat& gray) override;
  std::string name() const override { return "xfeat"; }

  const XFeatOptions& options() const { return options_; }
  const inference::OnnxModel& model() const { return model_; }
  /// Durations of the last extract() [ms]: whole call, and the network run alone.
  double lastExtractMs() const { return last_extract_ms_; }
  double lastInferenceMs() const { return model_.lastRunMs(); }

  /// The contract an XFeat model must satisfy under these options.
  static inference::ModelSignature signature(const XFeatOptions& options);

 private:
  XFeatOptions options_;
  inference::OnnxModel model_;
  std::vector<float> input_;  ///< Scratch: the network input.
  double last_extract_ms_ = 0.0;
};

}  // namespace superdyna::features

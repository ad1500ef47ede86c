#pragma once
// SuperPoint keypoints and descriptors (DeTone, Malisiewicz & Rabinovich, "SuperPoint:
// Self-Supervised Interest Point Detection and Description", CVPRW 2018) from an ONNX model with
// SuperPoint's contract: input [1,1,H,W] gray in [0,1] (H, W multiples of 8), or [1,3,H,W] RGB
// in [0,1] (models trained on colour, e.g. SuperPoint-Optimized: the gray image goes into all three
// channels); outputs `semi` [1,65,H/8,W/8] (cell logits + dustbin) and `desc` [1,D,H/8,W/8]
// (D = 256 for MagicLeap's weights; any D is accepted).
//
// SuperPoint weights are not redistributable here: scripts/export_superpoint_onnx.py exports
// MagicLeap's superpoint_v1.pth; scripts/make_superpoint_from_xfeat.py builds a model with the
// same contract from xfeat.onnx (docs/concepts/learned-features.md).
//
// extract() decodes as MagicLeap's SuperPointFrontend does (keypoint_decoding.h):
//  1. gray / 255, padded (or resized) to multiples of 8 (or of the model's metadata
//     "superdyna.size_multiple" when larger: the XFeat-based model needs 32);
//  2. heatmap = depth-to-space(softmax over the 65 logits, dustbin dropped);
//  3. candidates with heat >= 0.015 inside the image;
//  4. greedy non-maximum suppression, radius 4 (square);
//  5. candidates closer than 4 px to the image border dropped;
//  6. the top-K scores (1200), optionally spread over a grid;
//  7. descriptors sampled bilinearly from the 1/8 map at the keypoints, L2-normalised.
// Differences from MagicLeap's demo, all below what affects matching: the softmax has no 1e-5
// added to its denominator; descriptors are sampled with the pixel-centre convention of
// keypoint_decoding.h instead of grid_sample(align_corners=True) on [0, W].
// Keypoints carry the heat as response, no angle (-1), octave 0 and size 8 (one cell).

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "superdyna/features/feature_set.h"
#include "superdyna/features/keypoint_decoding.h"
#include "superdyna/inference/onnx_model.h"

namespace superdyna::features {

struct SuperPointOptions {
  /// Model file (inference::findModel() for a bare name, else the path as given).
  std::string model = "superpoint.onnx";
  int max_keypoints = 1200;             ///< Top-K, >= 1.
  float confidence_threshold = 0.015f;  ///< Heat a candidate needs, in [0, 1).
  int nms_radius = 4;                   ///< Greedy NMS radius [px], >= 0 (0: no NMS).
  int border = 4;                       ///< Keypoints keep this distance from the border [px].
  int grid_cell_px = 0;                 ///< Spread the top-K over cells of this side; 0: off.
  /// Input sides are brought to multiples of this (or of the model's metadata, if larger), >= 8
  /// and a multiple of 8.
  int size_multiple = 8;
  FitMode fit = FitMode::kPad;
  /// The image is scaled by this factor, in (0, 1], before the network sees it (keypoints are
  /// returned in the original image's pixels): fewer pixels, a faster network.
  double input_scale = 1.0;
  cv::Size warmup_size;  ///< Warm-up image size at construction (empty: none).
  /// Output names (the input is taken by position).
  std::string scores_output = "semi";
  std::string descriptors_output = "desc";
  inference::OnnxModelOptions runtime;

  /// Throws OptionError naming the first invalid field.
  void validate() const;
};

/// SuperPoint extractor; see the file comment. Deterministic for a given thread count.
class SuperPointExtractor final : public FeatureExtractor {
 public:
  /// Loads the model and checks its contract (input [any,1 or 3,8k,8k] float; `semi` with 65
  /// channels; `desc` of rank 4): InputError naming the model file and the tensor otherwise.
  explicit SuperPointExtractor(const SuperPointOptions& options = {});

  /// Keypoints sorted by decreasing heat; descriptors CV_32FC1, D floats of unit norm per row;
  /// DescriptorType::kFloat. Throws InputError unless `gray` is a non-empty CV_8UC1 image.
  FeatureSet extract(const cv::Mat& gray) override;
  std::string name() const override { return "superpoint"; }

  const SuperPointOptions& options() const { return options_; }
  const inference::OnnxModel& model() const { return model_; }
  /// The effective size multiple (options and model metadata).
  int sizeMultiple() const { return size_multiple_; }
  /// Input channels the model takes: 1 (gray) or 3 (the gray image replicated).
  int inputChannels() const { return input_channels_; }
  double lastExtractMs() const { return last_extract_ms_; }
  double lastInferenceMs() const { return model_.lastRunMs(); }

  static inference::ModelSignature signature(const SuperPointOptions& options);
  /// Metadata key a model can use to require a larger input multiple.
  static constexpr const char* kSizeMultipleKey = "superdyna.size_multiple";

 private:
  SuperPointOptions options_;
  inference::OnnxModel model_;
  int size_multiple_ = 8;
  int input_channels_ = 1;
  std::vector<float> input_;
  double last_extract_ms_ = 0.0;
};

}  // namespace superdyna::features

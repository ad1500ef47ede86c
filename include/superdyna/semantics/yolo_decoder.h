#pragma once
// Decoding of an Ultralytics YOLOv8-seg / YOLO11-seg ONNX export, step by step (each step is
// checked against a numpy reference, tests/semantics/yolo_reference.py):
//   1. letterbox: the image scaled by r = min(W / w, H / h) to (round(w r), round(h r)) and
//      centred in the W x H input (padding left = round(dw - 0.1), top = round(dh - 0.1), as
//      Ultralytics pads; grey 114);
//   2. detections: output0 [1, 4 + C + M, N] holds per anchor the box (cx, cy, w, h in input
//      pixels), C class scores (already sigmoid) and M mask coefficients; an anchor is a detection
//      of its best class when that score reaches the threshold and the class is wanted;
//   3. class-aware NMS: best score first (ties: lower anchor), a box is dropped when its IoU with a
//      kept box of its class exceeds the threshold; at most max_detections kept;
//   4. masks: sigmoid(coefficients . prototypes) on the prototype grid (output1 [1, M, H/4, W/4]),
//      sampled bilinearly (pixel centres, clamped at the border) at each image pixel's centre
//      mapped into the input, kept inside the detection box (in input pixels, x1 <= u < x2),
//      thresholded;
//   5. instances: best score first, each takes its mask's pixels not taken yet; instances left
//      with fewer than min_area pixels are dropped; ids 1, 2, ... in that order.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "superdyna/semantics/segmenter.h"

namespace superdyna::semantics {

/// Where an image lies in the network input.
struct Letterbox {
  double scale = 1.0;  ///< Input pixels per image pixel.
  int left = 0;        ///< Padding columns left of the scaled image.
  int top = 0;         ///< Padding rows above it.
  cv::Size scaled;     ///< Size of the scaled image inside the input.
  cv::Size input;      ///< Network input size.
};

Letterbox letterboxFor(cv::Size image, cv::Size input);

/// The network input: the image (CV_8UC1 replicated to RGB, or CV_8UC3 BGR) letterboxed, as
/// float RGB in [0, 1], planar [1, 3, H, W].
std::vector<float> letterboxedInput(const cv::Mat& image, const Letterbox& letterbox);

/// A CV_8UC3 image as planar floats [3, H, W] in its own channel order, each value / `divisor`.
std::vector<float> planarFloats(const cv::Mat& image, float divisor);

/// One detection in input pixels.
struct YoloDetection {
  int anchor = 0;
  int class_index = 0;  ///< Index into the model's labels.
  float score = 0.0f;
  double x1 = 0, y1 = 0, x2 = 0, y2 = 0;  ///< Box in input pixels.
  std::vector<float> coefficients;        ///< Mask coefficients.
};

/// Step 2 on output0 of shape [1, channels, anchors] (channels = 4 + wanted.size() + M).
std::vector<YoloDetection> decodeDetections(const float* output0, int channels, int anchors,
                                            const std::vector<bool>& wanted,
                                            double score_threshold);

/// Step 3: the kept detections, best first.
std::vector<YoloDetection> classAwareNms(std::vector<YoloDetection> detections, double iou,
                                         int max_detections);

/// Step 4: the mask (CV_8UC1, 255 on the instance) of one detection in an image of `image`
/// size; protos [M, ph, pw] row-major.
cv::Mat detectionMask(const YoloDetection& detection, const float* protos, int proto_h, int proto_w,
                      const Letterbox& letterbox, cv::Size image, double mask_threshold);

/// Tensors of one run as the decoder reads them.
struct YoloOutputs {
  const float* output0 = nullptr;
  int channels = 0;
  int anchors = 0;
  const float* protos = nullptr;
  int masks = 0;  ///< M.
  int proto_h = 0;
  int proto_w = 0;
};

/// Steps 2 to 5: the segmentation of an image of `image` size; `labels` are the model's class
/// names (their count is C), mapped to classes by `taxonomy`.
Segmentation decodeSegmentation(const YoloOutputs& outputs, const Letterbox& letterbox,
                                cv::Size image, const std::vector<std::string>& labels,
                                const Taxonomy& taxonomy, const YoloOptions& options);

/// The class names of an Ultralytics export's "names" metadata ("{0: 'person', 1: 'bicycle'}");
/// empty when the text does not parse.
std::vector<std::string> parseUltralyticsNames(const std::string& text);

}  // namespace superdyna::semantics

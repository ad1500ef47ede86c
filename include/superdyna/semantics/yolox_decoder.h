#pragma once
// Decoding of a YOLOX detector exported to ONNX by Megvii's tools/export_onnx.py (boxes only, the
// grid decoding left out of the graph; yolox_nano.onnx, 416x416, COCO's 80 classes), as Megvii's
// demo decodes it (each step is checked against a numpy reference, tests/semantics/
// sam_reference.py):
//   1. input: the image scaled by r = min(W / w, H / h) to (floor(w r), floor(h r)) (bilinear),
//      at the top left of a W x H canvas of grey 114, BGR, float in [0, 255] (no normalisation),
//      planar [1, 3, H, W];
//   2. output [1, anchors, 5 + C]: per anchor of the grids of strides 8, 16 and 32 (each row-major,
//      W / s x H / s cells, in that order) the raw box (dx, dy, log w, log h), the objectness and
//      C class probabilities (sigmoids are in the graph); box centre = ((dx, dy) + cell) x stride,
//      size = exp(log w, log h) x stride; score = objectness x best class probability; a detection
//      when the score exceeds the threshold and the class is wanted;
//   3. class-aware NMS as the yolo backend's (classAwareNms, yolo_decoder.h);
//   4. boxes divided by r: image pixels.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "superdyna/semantics/yolo_decoder.h"

namespace superdyna::semantics {

/// COCO's 80 class names in the order of YOLOX's (and Ultralytics') class index.
const std::vector<std::string>& coco80Labels();

/// Step 1's geometry: scale r, the scaled image's size (floor), no padding before it.
Letterbox yoloxLetterboxFor(cv::Size image, cv::Size input);

/// Step 1: the network input (CV_8UC1 replicated, or CV_8UC3 BGR kept BGR), [1, 3, H, W].
std::vector<float> yoloxInput(const cv::Mat& image, const Letterbox& letterbox);

/// Number of anchors of an input of this size: the cells of the stride 8, 16 and 32 grids.
int yoloxAnchorCount(cv::Size input);

/// Step 2 on output [1, anchors, 5 + wanted.size()] of an input of `input` size: detections in
/// input pixels (YoloDetection without mask coefficients). InputError when the anchor or channel
/// count does not fit the input size and the class count.
std::vector<YoloDetection> decodeYoloxDetections(const float* output, int anchors, int channels,
                                                 cv::Size input, const std::vector<bool>& wanted,
                                                 double score_threshold);

/// Step 4: a detection's box in image pixels (not clipped).
YoloDetection toImagePixels(YoloDetection detection, const Letterbox& letterbox);

/// Steps 2 to 4: the kept detections in image pixels, best first.
std::vector<YoloDetection> yoloxDetections(const float* output, int anchors, int channels,
                                           const Letterbox& letterbox,
                                           const std::vector<bool>& wanted, double score_threshold,
                                           double nms_iou, int max_detections);

}  // namespace superdyna::semantics

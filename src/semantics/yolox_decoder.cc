#include "superdyna/semantics/yolox_decoder.h"

#include <fmt/format.h>

#include <array>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "superdyna/core/error.h"

namespace superdyna::semantics {

namespace {

constexpr std::array<int, 3> kStrides = {8, 16, 32};
constexpr int kBoxChannels = 5;  // dx, dy, log w, log h, objectness.

}  // namespace

const std::vector<std::string>& coco80Labels() {
  static const std::vector<std::string> labels = {"person",        "bicycle",      "car",
                                                  "motorcycle",    "airplane",     "bus",
                                                  "train",         "truck",        "boat",
                                                  "traffic light", "fire hydrant", "stop sign",
                                                  "parking meter", "bench",        "bird",
                                                  "cat",           "dog",          "horse",
                                                  "sheep",         "cow",          "elephant",
                                                  "bear",          "zebra",        "giraffe",
                                                  "backpack",      "umbrella",     "handbag",
                                                  "tie",           "suitcase",     "frisbee",
                                                  "skis",          "snowboard",    "sports ball",
                                                  "kite",          "baseball bat", "baseball glove",
                                                  "skateboard",    "surfboard",    "tennis racket",
                                                  "bottle",        "wine glass",   "cup",
                                                  "fork",          "knife",        "spoon",
                                                  "bowl",          "banana",       "apple",
                                                  "sandwich",      "orange",       "broccoli",
                                                  "carrot",        "hot dog",      "pizza",
                                                  "donut",         "cake",         "chair",
                                                  "couch",         "potted plant", "bed",
                                                  "dining table",  "toilet",       "tv",
                                                  "laptop",        "mouse",        "remote",
                                                  "keyboard",      "cell phone",   "microwave",
                                                  "oven",          "toaster",      "sink",
                                                  "refrigerator",  "book",         "clock",
                                                  "vase",          "scissors",     "teddy bear",
                                                  "hair drier",    "toothbrush"};
  return labels;
}

Letterbox yoloxLetterboxFor(cv::Size image, cv::Size input) {
  Letterbox letterbox;
  letterbox.input = input;
  letterbox.scale =
      std::min(double(input.width) / image.width, double(input.height) / image.height);
  letterbox.scaled = cv::Size(static_cast<int>(image.width * letterbox.scale),
                              static_cast<int>(image.height * letterbox.scale));
  return letterbox;
}

std::vector<float> yoloxInput(const cv::Mat& image, const Letterbox& letterbox) {
  cv::Mat bgr;
  if (image.channels() == 1) {
    cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
  } else {
    bgr = image;
  }
  cv::Mat scaled;
  cv::resize(bgr, scaled, letterbox.scaled, 0, 0, cv::INTER_LINEAR);
  cv::Mat canvas(letterbox.input, CV_8UC3, cv::Scalar(114, 114, 114));
  scaled.copyTo(canvas(cv::Rect(cv::Point(0, 0), letterbox.scaled)));
  return planarFloats(canvas, 1.0f);
}

int yoloxAnchorCount(cv::Size input) {
  int anchors = 0;
  for (const int stride : kStrides)
    anchors += (input.width / stride) * (input.height / stride);
  return anchors;
}

std::vector<YoloDetection> decodeYoloxDetections(const float* output, int anchors, int channels,
                                                 cv::Size input, const std::vector<bool>& wanted,
                                                 double score_threshold) {
  const int classes = static_cast<int>(wanted.size());
  if (channels != kBoxChannels + classes) {
    throw InputError(fmt::format("YOLOX output has {} channels per anchor, expected 5 + {} classes",
                                 channels, classes));
  }
  if (anchors != yoloxAnchorCount(input)) {
    throw InputError(
        fmt::format("YOLOX output has {} anchors; a {}x{} input has {} (strides 8, 16, 32)",
                    anchors, input.width, input.height, yoloxAnchorCount(input)));
  }
  std::vector<YoloDetection> detections;
  int a = 0;
  for (const int stride : kStrides) {
    const int cols = input.width / stride, rows = input.height / stride;
    for (int cell = 0; cell < rows * cols; ++cell, ++a) {
      const float* row = output + static_cast<std::size_t>(a) * channels;
      int best = 0;
      for (int c = 1; c < classes; ++c)
        if (row[kBoxChannels + c] > row[kBoxChannels + best]) best = c;
      const float score = row[4] * row[kBoxChannels + best];
      if (!(score > score_threshold) || !wanted[static_cast<std::size_t>(best)]) continue;
      const double cx = (double(row[0]) + cell % cols) * stride;
      const double cy = (double(row[1]) + cell / cols) * stride;
      const double w = std::exp(double(row[2])) * stride;
      const double h = std::exp(double(row[3])) * stride;
      YoloDetection d;
      d.anchor = a;
      d.class_index = best;
      d.score = score;
      d.x1 = cx - w / 2;
      d.y1 = cy - h / 2;
      d.x2 = cx + w / 2;
      d.y2 = cy + h / 2;
      detections.push_back(std::move(d));
    }
  }
  return detections;
}

YoloDetection toImagePixels(YoloDetection detection, const Letterbox& letterbox) {
  detection.x1 /= letterbox.scale;
  detection.y1 /= letterbox.scale;
  detection.x2 /= letterbox.scale;
  detection.y2 /= letterbox.scale;
  return detection;
}

std::vector<YoloDetection> yoloxDetections(const float* output, int anchors, int channels,
                                           const Letterbox& letterbox,
                                           const std::vector<bool>& wanted, double score_threshold,
                                           double nms_iou, int max_detections) {
  std::vector<YoloDetection> detections = classAwareNms(
      decodeYoloxDetections(output, anchors, channels, letterbox.input, wanted, score_threshold),
      nms_iou, max_detections);
  for (YoloDetection& d : detections)
    d = toImagePixels(std::move(d), letterbox);
  return detections;
}

}  // namespace superdyna::semantics

#include "superdyna/semantics/yolo_decoder.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <opencv2/imgproc.hpp>

#include "superdyna/core/error.h"
#include "superdyna/semantics/instance_assembly.h"

namespace superdyna::semantics {

namespace {

/// Python's round(): halves to even (the default rounding mode of nearbyint).
int roundHalfEven(double value) {
  return static_cast<int>(std::nearbyint(value));
}

double areaOf(const YoloDetection& d) {
  return std::max(0.0, d.x2 - d.x1) * std::max(0.0, d.y2 - d.y1);
}

double iouOf(const YoloDetection& a, const YoloDetection& b) {
  const double w = std::min(a.x2, b.x2) - std::max(a.x1, b.x1);
  const double h = std::min(a.y2, b.y2) - std::max(a.y1, b.y1);
  const double inter = std::max(0.0, w) * std::max(0.0, h);
  const double uni = areaOf(a) + areaOf(b) - inter;
  return uni > 0.0 ? inter / uni : 0.0;
}

/// sigmoid(coefficients . prototypes) at every prototype cell.
std::vector<double> maskProbabilities(const YoloDetection& detection, const float* protos,
                                      int cells) {
  std::vector<double> logits(static_cast<std::size_t>(cells), 0.0);
  for (std::size_t m = 0; m < detection.coefficients.size(); ++m) {
    const double coefficient = detection.coefficients[m];
    const float* proto = protos + m * static_cast<std::size_t>(cells);
    for (int i = 0; i < cells; ++i)
      logits[static_cast<std::size_t>(i)] += coefficient * proto[i];
  }
  for (double& v : logits)
    v = 1.0 / (1.0 + std::exp(-v));
  return logits;
}

/// The detection box in image pixels, clipped to the image.
cv::Rect imageBox(const YoloDetection& d, const Letterbox& letterbox, cv::Size image) {
  const auto toX = [&](double u) { return (u - letterbox.left) / letterbox.scale; };
  const auto toY = [&](double v) { return (v - letterbox.top) / letterbox.scale; };
  return pixelBox(toX(d.x1), toY(d.y1), toX(d.x2), toY(d.y2), image);
}

}  // namespace

Letterbox letterboxFor(cv::Size image, cv::Size input) {
  Letterbox letterbox;
  letterbox.input = input;
  letterbox.scale =
      std::min(double(input.width) / image.width, double(input.height) / image.height);
  letterbox.scaled = cv::Size(roundHalfEven(image.width * letterbox.scale),
                              roundHalfEven(image.height * letterbox.scale));
  letterbox.left = roundHalfEven((input.width - letterbox.scaled.width) / 2.0 - 0.1);
  letterbox.top = roundHalfEven((input.height - letterbox.scaled.height) / 2.0 - 0.1);
  return letterbox;
}

std::vector<float> letterboxedInput(const cv::Mat& image, const Letterbox& letterbox) {
  cv::Mat rgb;
  if (image.channels() == 1) {
    cv::cvtColor(image, rgb, cv::COLOR_GRAY2RGB);
  } else {
    cv::cvtColor(image, rgb, cv::COLOR_BGR2RGB);
  }
  cv::Mat scaled;
  if (rgb.size() == letterbox.scaled) {
    scaled = rgb;
  } else {
    cv::resize(rgb, scaled, letterbox.scaled, 0, 0, cv::INTER_LINEAR);
  }
  cv::Mat canvas(letterbox.input, CV_8UC3, cv::Scalar(114, 114, 114));
  scaled.copyTo(canvas(cv::Rect(cv::Point(letterbox.left, letterbox.top), letterbox.scaled)));
  return planarFloats(canvas, 255.0f);
}

std::vector<float> planarFloats(const cv::Mat& image, float divisor) {
  const std::size_t plane = static_cast<std::size_t>(image.rows) * image.cols;
  std::vector<float> planar(3 * plane);
  for (int r = 0; r < image.rows; ++r) {
    const auto* row = image.ptr<cv::Vec3b>(r);
    for (int c = 0; c < image.cols; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * image.cols + c;
      for (int k = 0; k < 3; ++k)
        planar[k * plane + i] = row[c][k] / divisor;
    }
  }
  return planar;
}

std::vector<YoloDetection> decodeDetections(const float* output0, int channels, int anchors,
                                            const std::vector<bool>& wanted,
                                            double score_threshold) {
  const int classes = static_cast<int>(wanted.size());
  const int masks = channels - 4 - classes;
  if (masks < 0) {
    throw InputError(
        fmt::format("YOLO output0 has {} channels, fewer than 4 + {} classes", channels, classes));
  }
  const auto at = [&](int channel, int anchor) {
    return output0[static_cast<std::size_t>(channel) * anchors + anchor];
  };
  std::vector<YoloDetection> detections;
  for (int a = 0; a < anchors; ++a) {
    int best = 0;
    for (int c = 1; c < classes; ++c)
      if (at(4 + c, a) > at(4 + best, a)) best = c;
    const float score = at(4 + best, a);
    if (!(score > score_threshold) || !wanted[static_cast<std::size_t>(best)]) continue;
    YoloDetection d;
    d.anchor = a;
    d.class_index = best;
    d.score = score;
    const double cx = at(0, a), cy = at(1, a), w = at(2, a), h = at(3, a);
    d.x1 = cx - w / 2;
    d.y1 = cy - h / 2;
    d.x2 = cx + w / 2;
    d.y2 = cy + h / 2;
    d.coefficients.resize(static_cast<std::size_t>(masks));
    for (int m = 0; m < masks; ++m)
      d.coefficients[static_cast<std::size_t>(m)] = at(4 + classes + m, a);
    detections.push_back(std::move(d));
  }
  return detections;
}

std::vector<YoloDetection> classAwareNms(std::vector<YoloDetection> detections, double iou,
                                         int max_detections) {
  std::stable_sort(
      detections.begin(), detections.end(),
      [](const YoloDetection& a, const YoloDetection& b) { return a.score > b.score; });
  std::vector<YoloDetection> kept;
  for (YoloDetection& candidate : detections) {
    if (static_cast<int>(kept.size()) >= max_detections) break;
    const bool suppressed = std::any_of(kept.begin(), kept.end(), [&](const YoloDetection& k) {
      return k.class_index == candidate.class_index && iouOf(k, candidate) > iou;
    });
    if (!suppressed) kept.push_back(std::move(candidate));
  }
  return kept;
}

cv::Mat detectionMask(const YoloDetection& detection, const float* protos, int proto_h, int proto_w,
                      const Letterbox& letterbox, cv::Size image, double mask_threshold) {
  const std::vector<double> probability = maskProbabilities(detection, protos, proto_h * proto_w);
  const double stride_x = double(letterbox.input.width) / proto_w;
  const double stride_y = double(letterbox.input.height) / proto_h;
  cv::Mat mask(image, CV_8UC1, cv::Scalar(0));
  // Image pixels whose centre can lie in the box (one pixel of margin; tested exactly below).
  const cv::Rect box = imageBox(detection, letterbox, image);
  const cv::Rect region = (box + cv::Size(2, 2) - cv::Point(1, 1)) & cv::Rect(cv::Point(), image);
  for (int y = region.y; y < region.y + region.height; ++y) {
    const double v = (y + 0.5) * letterbox.scale + letterbox.top;
    if (!(v >= detection.y1 && v < detection.y2)) continue;
    auto* row = mask.ptr<std::uint8_t>(y);
    for (int x = region.x; x < region.x + region.width; ++x) {
      const double u = (x + 0.5) * letterbox.scale + letterbox.left;
      if (!(u >= detection.x1 && u < detection.x2)) continue;
      const double p =
          sampleBilinear(probability, proto_w, proto_h, u / stride_x - 0.5, v / stride_y - 0.5);
      if (p > mask_threshold) row[x] = 255;
    }
  }
  return mask;
}

Segmentation decodeSegmentation(const YoloOutputs& outputs, const Letterbox& letterbox,
                                cv::Size image, const std::vector<std::string>& labels,
                                const Taxonomy& taxonomy, const YoloOptions& options) {
  const int classes = outputs.channels - 4 - outputs.masks;
  if (classes != static_cast<int>(labels.size())) {
    throw InputError(
        fmt::format("YOLO output0 has {} classes ({} channels - 4 box - {} mask "
                    "coefficients) but the model names {} labels",
                    classes, outputs.channels, outputs.masks, labels.size()));
  }
  std::vector<bool> wanted(labels.size());
  for (std::size_t c = 0; c < labels.size(); ++c)
    wanted[c] = taxonomy.classOf(labels[c]) != sensors::kInstanceClassBackground;
  const std::vector<YoloDetection> detections =
      classAwareNms(decodeDetections(outputs.output0, outputs.channels, outputs.anchors, wanted,
                                     options.score_threshold),
                    options.nms_iou, options.max_detections);

  InstanceAssembler assembler(image, options.min_area_px);
  for (const YoloDetection& d : detections) {
    Instance instance;
    instance.label = labels[static_cast<std::size_t>(d.class_index)];
    instance.class_id = taxonomy.classOf(instance.label);
    instance.score = d.score;
    instance.box = imageBox(d, letterbox, image);
    assembler.add(std::move(instance),
                  detectionMask(d, outputs.protos, outputs.proto_h, outputs.proto_w, letterbox,
                                image, options.mask_threshold));
  }
  return assembler.segmentation();
}

std::vector<std::string> parseUltralyticsNames(const std::string& text) {
  std::vector<std::string> names;
  std::size_t pos = 0;
  while (true) {
    const std::size_t colon = text.find(':', pos);
    if (colon == std::string::npos) break;
    const std::size_t open = text.find_first_of("'\"", colon);
    if (open == std::string::npos) return {};
    const std::size_t close = text.find(text[open], open + 1);
    if (close == std::string::npos) return {};
    names.push_back(text.substr(open + 1, close - open - 1));
    pos = close + 1;
  }
  return names;
}

}  // namespace superdyna::semantics

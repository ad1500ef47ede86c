#include "superdyna/semantics/maskrcnn_decoder.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>

#include "superdyna/core/error.h"
#include "superdyna/semantics/instance_assembly.h"

namespace superdyna::semantics {

namespace {

struct Box {
  double x1 = 0, y1 = 0, x2 = 0, y2 = 0;
};

Box boxOf(const MaskRcnnOutputs& outputs, int index) {
  const float* b = outputs.boxes + 4 * static_cast<std::size_t>(index);
  return {b[0], b[1], b[2], b[3]};
}

const float* softMaskOf(const MaskRcnnOutputs& outputs, int index) {
  return outputs.masks + static_cast<std::size_t>(index) *
                             static_cast<std::size_t>(outputs.mask_h) * outputs.mask_w;
}

/// The category name of a label value; InputError when it is no id of the list.
const std::string& categoryOf(float label) {
  const std::vector<std::string>& categories = torchvisionCocoCategories();
  if (!(label >= 0 && label < static_cast<float>(categories.size())) ||
      label != std::floor(label)) {
    throw InputError(
        fmt::format("Mask R-CNN label {} is not a category id of torchvision's COCO "
                    "list (0 to {})",
                    label, categories.size() - 1));
  }
  return categories[static_cast<std::size_t>(label)];
}

/// Step 1: indices of the wanted detections above the threshold, best first.
std::vector<int> rankedDetections(const MaskRcnnOutputs& outputs, const Taxonomy& taxonomy,
                                  const MaskRcnnOptions& options) {
  std::vector<int> kept;
  for (int i = 0; i < outputs.detections; ++i) {
    const std::string& category = categoryOf(outputs.labels[i]);
    if (!(outputs.scores[i] > options.score_threshold)) continue;
    if (taxonomy.classOf(category) == sensors::kInstanceClassBackground) continue;
    kept.push_back(i);
  }
  std::stable_sort(kept.begin(), kept.end(),
                   [&](int a, int b) { return outputs.scores[a] > outputs.scores[b]; });
  if (static_cast<int>(kept.size()) > options.max_detections) {
    kept.resize(static_cast<std::size_t>(options.max_detections));
  }
  return kept;
}

cv::Mat imageResolutionMask(const float* soft, cv::Size image, double mask_threshold) {
  cv::Mat mask(image, CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < image.height; ++y) {
    const float* in = soft + static_cast<std::size_t>(y) * image.width;
    auto* out = mask.ptr<std::uint8_t>(y);
    for (int x = 0; x < image.width; ++x)
      if (in[x] > mask_threshold) out[x] = 255;
  }
  return mask;
}

cv::Mat boxResolutionMask(const float* soft, int mask_h, int mask_w, const Box& box, cv::Size image,
                          double mask_threshold) {
  cv::Mat mask(image, CV_8UC1, cv::Scalar(0));
  const double box_w = box.x2 - box.x1, box_h = box.y2 - box.y1;
  if (!(box_w > 0 && box_h > 0)) return mask;
  const std::vector<double> grid(soft, soft + static_cast<std::size_t>(mask_h) * mask_w);
  const cv::Rect region = pixelBox(box.x1 - 1, box.y1 - 1, box.x2 + 1, box.y2 + 1, image);
  for (int y = region.y; y < region.y + region.height; ++y) {
    const double v = y + 0.5;
    if (!(v >= box.y1 && v < box.y2)) continue;
    auto* row = mask.ptr<std::uint8_t>(y);
    for (int x = region.x; x < region.x + region.width; ++x) {
      const double u = x + 0.5;
      if (!(u >= box.x1 && u < box.x2)) continue;
      const double p = sampleBilinear(grid, mask_w, mask_h, (u - box.x1) / box_w * mask_w - 0.5,
                                      (v - box.y1) / box_h * mask_h - 0.5);
      if (p > mask_threshold) row[x] = 255;
    }
  }
  return mask;
}

}  // namespace

const std::vector<std::string>& torchvisionCocoCategories() {
  static const std::vector<std::string> categories = {"__background__",
                                                      "person",
                                                      "bicycle",
                                                      "car",
                                                      "motorcycle",
                                                      "airplane",
                                                      "bus",
                                                      "train",
                                                      "truck",
                                                      "boat",
                                                      "traffic light",
                                                      "fire hydrant",
                                                      "N/A",
                                                      "stop sign",
                                                      "parking meter",
                                                      "bench",
                                                      "bird",
                                                      "cat",
                                                      "dog",
                                                      "horse",
                                                      "sheep",
                                                      "cow",
                                                      "elephant",
                                                      "bear",
                                                      "zebra",
                                                      "giraffe",
                                                      "N/A",
                                                      "backpack",
                                                      "umbrella",
                                                      "N/A",
                                                      "N/A",
                                                      "handbag",
                                                      "tie",
                                                      "suitcase",
                                                      "frisbee",
                                                      "skis",
                                                      "snowboard",
                                                      "sports ball",
                                                      "kite",
                                                      "baseball bat",
                                                      "baseball glove",
                                                      "skateboard",
                                                      "surfboard",
                                                      "tennis racket",
                                                      "bottle",
                                                      "N/A",
                                                      "wine glass",
                                                      "cup",
                                                      "fork",
                                                      "knife",
                                                      "spoon",
                                                      "bowl",
                                                      "banana",
                                                      "apple",
                                                      "sandwich",
                                                      "orange",
                                                      "broccoli",
                                                      "carrot",
                                                      "hot dog",
                                                      "pizza",
                                                      "donut",
                                                      "cake",
                                                      "chair",
                                                      "couch",
                                                      "potted plant",
                                                      "bed",
                                                      "N/A",
                                                      "dining table",
                                                      "N/A",
                                                      "N/A",
                                                      "toilet",
                                                      "N/A",
                                                      "tv",
                                                      "laptop",
                                                      "mouse",
                                                      "remote",
                                                      "keyboard",
                                                      "cell phone",
                                                      "microwave",
                                                      "oven",
                                                      "toaster",
                                                      "sink",
                                                      "refrigerator",
                                                      "N/A",
                                                      "book",
                                                      "clock",
                                                      "vase",
                                                      "scissors",
                                                      "teddy bear",
                                                      "hair drier",
                                                      "toothbrush"};
  return categories;
}

cv::Mat maskRcnnMask(const MaskRcnnOutputs& outputs, int index, cv::Size image,
                     double mask_threshold) {
  const float* soft = softMaskOf(outputs, index);
  if (outputs.mask_h == image.height && outputs.mask_w == image.width) {
    return imageResolutionMask(soft, image, mask_threshold);
  }
  return boxResolutionMask(soft, outputs.mask_h, outputs.mask_w, boxOf(outputs, index), image,
                           mask_threshold);
}

Segmentation decodeMaskRcnn(const MaskRcnnOutputs& outputs, cv::Size image,
                            const Taxonomy& taxonomy, const MaskRcnnOptions& options) {
  if (outputs.detections > 0 && (outputs.mask_h < 1 || outputs.mask_w < 1)) {
    throw InputError(fmt::format("Mask R-CNN masks are {}x{}", outputs.mask_w, outputs.mask_h));
  }
  InstanceAssembler assembler(image, options.min_area_px);
  for (const int i : rankedDetections(outputs, taxonomy, options)) {
    const Box box = boxOf(outputs, i);
    Instance instance;
    instance.label = categoryOf(outputs.labels[i]);
    instance.class_id = taxonomy.classOf(instance.label);
    instance.score = outputs.scores[i];
    instance.box = pixelBox(box.x1, box.y1, box.x2, box.y2, image);
    assembler.add(std::move(instance), maskRcnnMask(outputs, i, image, options.mask_threshold));
  }
  return assembler.segmentation();
}

}  // namespace superdyna::semantics

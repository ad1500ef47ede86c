#pragma once
// Decoding of torchvision's Mask R-CNN ONNX export (maskrcnn_resnet50_fpn and its relatives; the
// network resizes the image, runs NMS and maps everything back to the input image itself):
//   - boxes [N, 4]: x1, y1, x2, y2 in input pixels; labels [N] (int64): category ids of
//     torchvision's 91-entry COCO list (torchvisionCocoCategories(): 0 background, "N/A" at the
//     ids COCO left unused — not the 80-line coco.names order); scores [N];
//     masks [N, 1, h, w]: soft masks in [0, 1], either at the image's size (torchvision pastes
//     them into the image) or at any other size, taken as covering the detection box.
// Steps, as the yolo backend's last ones (instance_assembly.h):
//   1. detections whose score exceeds the threshold and whose label the taxonomy wants (not
//      background, "N/A" or unlisted), best score first (ties: lower index), at most
//      max_detections;
//   2. mask: an image-size mask is the pixels whose value exceeds the mask threshold; a
//      box-resolution mask is sampled bilinearly (cell centres, clamped at the border) at the
//      centre of each image pixel inside the box (x1 <= x + 0.5 < x2), mapped to the mask grid
//      spanning the box, and thresholded;
//   3. instances: best score first, each takes its mask's pixels not taken yet; fewer than
//      min_area pixels left drops it; ids 1, 2, ... in that order. The box is the detection box
//      (pixelBox()).

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "superdyna/semantics/segmenter.h"

namespace superdyna::semantics {

/// torchvision's COCO category names, index = label id: 91 entries, "__background__" at 0 and
/// "N/A" at 12, 26, 29, 30, 45, 66, 68, 69, 71 and 83.
const std::vector<std::string>& torchvisionCocoCategories();

/// Tensors of one run as the decoder reads them (row-major; labels as floats).
struct MaskRcnnOutputs {
  int detections = 0;  ///< N.
  const float* boxes = nullptr;
  const float* labels = nullptr;
  const float* scores = nullptr;
  const float* masks = nullptr;
  int mask_h = 0;  ///< Mask grid size; the image's size = image-resolution masks.
  int mask_w = 0;
};

/// Step 2: the mask (CV_8UC1, 255 on the instance) of detection `index`.
cv::Mat maskRcnnMask(const MaskRcnnOutputs& outputs, int index, cv::Size image,
                     double mask_threshold);

/// Steps 1 to 3: the segmentation of an image of `image` size. InputError for a label that is not
/// an id of torchvisionCocoCategories().
Segmentation decodeMaskRcnn(const MaskRcnnOutputs& outputs, cv::Size image,
                            const Taxonomy& taxonomy, const MaskRcnnOptions& options);

}  // namespace superdyna::semantics

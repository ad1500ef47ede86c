#pragma once
// The dataset backend: a sequence's own segmentation, looked up by the image's time, of an
// EuRoC-layout folder.
//   - "masks": mav0/camN/mask/<image file name>, 16-bit instance ids, with the classes of
//     mav0/instances.csv (the simulator's ground truth; io::EurocDataset::loadInstanceMask).
//   - "color": mav0/camN/segmentation/<image file name>, VIODE-style colour segmentation images:
//     each colour is an object id through a colour table ("id,r,g,b" rows: VIODE's rgb_ids.txt;
//     the simulator's mav0/segmentation_colors.csv), and the objects of a movable-id list
//     (VIODE's vehicle_ids_<scene>.txt, "id, name" rows, all vehicles; by default the classes of
//     mav0/instances.csv) are the instances, with their object id as instance id; other objects
//     are background. A colour the table does not list is an error naming the file and pixel.

#include <cstdint>
#include <filesystem>
#include <map>

#include "superdyna/io/euroc_dataset.h"
#include "superdyna/semantics/segmenter.h"

namespace superdyna::semantics {

/// Colour (packRgb) -> object id of a colour table: "id,r,g,b" rows, an optional "id,r,g,b"
/// header, '#' comments. InputError naming file, line and field on a bad row or a colour listed
/// twice.
std::map<std::uint32_t, int> readColourTable(const std::filesystem::path& file);

/// Object id -> class (vehicle) of a VIODE movable-id list: "id, name" rows, an optional
/// "id, name" header.
std::map<int, int> readMovableIds(const std::filesystem::path& file);

/// What a stream of colour segmentation images (a bag's or a live node's topics) needs: colour ->
/// object id, and the classes of the movable objects.
struct ColourTables {
  std::map<std::uint32_t, int> object_of_colour;
  std::map<int, int> classes;
};

/// The tables of `options` (semantics.color_table, semantics.movable_ids), by default those of the
/// calibration folder (or its mav0/, or the folder of a calibration file):
/// segmentation_colors.csv and instances.csv as the simulator writes them. InputError naming the
/// file; also when no object is movable.
ColourTables readColourTables(const SegmenterOptions& options,
                              const std::filesystem::path& calibration);

inline std::uint32_t packRgb(int r, int g, int b) {
  return (static_cast<std::uint32_t>(r) << 16) | (static_cast<std::uint32_t>(g) << 8) |
         static_cast<std::uint32_t>(b);
}

/// The instances of a colour segmentation image (CV_8UC3, BGR as OpenCV reads it): objects with a
/// class in `classes` keep their object id, everything else is background. `file` names the image
/// in errors.
Segmentation segmentationFromColours(const cv::Mat& bgr,
                                     const std::map<std::uint32_t, int>& object_of_colour,
                                     const std::map<int, int>& classes,
                                     const std::filesystem::path& file);

/// An id image with classes (ids not in `classes` are an error of the caller) as a Segmentation:
/// label = the class name, score 1, boxes and areas from the pixels.
Segmentation segmentationFromIds(cv::Mat ids, const std::map<int, int>& classes);

class DatasetSegmenter : public Segmenter {
 public:
  /// Opens the EuRoC-layout sequence at `dataset` (InputError when it has no segmentation of the
  /// asked format, or the tables are bad).
  DatasetSegmenter(const std::filesystem::path& dataset, const SegmenterOptions& options);

  Segmentation segment(const cv::Mat& image, TimeNs t_ns, int camera) override;
  std::string description() const override;
  bool idsNameObjects() const override { return true; }

 private:
  /// The dataset's image of this camera and time; InputError when there is none.
  const std::filesystem::path& imageAt(TimeNs t_ns, int camera) const;

  io::EurocDataset dataset_;
  bool colour_ = false;
  std::map<std::uint32_t, int> object_of_colour_;
  std::map<int, int> classes_;  ///< Instance (object) id -> class.
  std::map<TimeNs, std::filesystem::path> images_[2];
};

}  // namespace superdyna::semantics

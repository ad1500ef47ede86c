#include "superdyna/semantics/id_png_segmenter.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "superdyna/core/error.h"
#include "superdyna/io/text_table.h"
#include "superdyna/semantics/maskrcnn_decoder.h"

namespace superdyna::semantics {

namespace fs = std::filesystem;

namespace {

constexpr int kClassIds[] = {sensors::kInstanceClassBackground, sensors::kInstanceClassVehicle,
                             sensors::kInstanceClassPedestrian,
                             sensors::kInstanceClassOtherMovable};

bool isCocoCategory(const std::string& label) {
  const std::vector<std::string>& categories = torchvisionCocoCategories();
  return label != "N/A" && label != categories.front() &&
         std::find(categories.begin(), categories.end(), label) != categories.end();
}

/// The class of a table label; InputError at `where` when it is unknown.
int classOfLabel(const std::string& label, const Taxonomy& taxonomy, const InputLocation& where) {
  for (const int class_id : kClassIds)
    if (label == sensors::instanceClassName(class_id)) return class_id;
  const int class_id = taxonomy.classOf(label);
  if (class_id != sensors::kInstanceClassBackground || isCocoCategory(label)) return class_id;
  throw InputError(where, fmt::format("unknown class '{}': expected background, vehicle, "
                                      "pedestrian, other_movable, a COCO category or a label of "
                                      "semantics.*_labels",
                                      label));
}

int parseInstanceId(const io::TextRow& row, const fs::path& file, std::size_t field) {
  const double value = io::parseFiniteDouble(row.fields[field], row.at(file, "id"));
  if (value != std::round(value) || value < 1 || value > UINT16_MAX) {
    throw InputError(row.at(file, "id"), "expected an integer in [1, 65535] (0 is background)");
  }
  return static_cast<int>(value);
}

bool isHeader(const io::TextRow& row, std::size_t index) {
  return index == 0 && !row.fields.empty() && (row.fields[0] == "id" || row.fields[0] == "t_ns");
}

/// Inserts a row's class; InputError when the key is listed already.
template <typename Key>
void insertClass(std::map<Key, IdClass>& classes, const Key& key, IdClass value,
                 const InputLocation& where) {
  if (!classes.emplace(key, std::move(value)).second) {
    throw InputError(where, "id listed twice");
  }
}

/// Ids of an id image with one pixel of each, in increasing id order.
std::map<int, cv::Point> idsIn(const cv::Mat& ids) {
  std::vector<bool> seen(UINT16_MAX + 1, false);
  std::map<int, cv::Point> found;
  for (int r = 0; r < ids.rows; ++r) {
    const auto* row = ids.ptr<std::uint16_t>(r);
    for (int c = 0; c < ids.cols; ++c) {
      if (row[c] == 0 || seen[row[c]]) continue;
      seen[row[c]] = true;
      found.emplace(row[c], cv::Point(c, r));
    }
  }
  return found;
}

fs::path tableOf(const std::string& option, const fs::path& folder) {
  return option.empty() ? folder / "classes.csv" : fs::path(option);
}

}  // namespace

const IdClass* IdClassTable::find(TimeNs t_ns, int id) const {
  if (const auto it = per_frame.find({t_ns, id}); it != per_frame.end()) return &it->second;
  if (const auto it = every_frame.find(id); it != every_frame.end()) return &it->second;
  return nullptr;
}

IdClassTable readIdClassTable(const fs::path& file, const Taxonomy& taxonomy) {
  IdClassTable table;
  table.file = file;
  const std::vector<io::TextRow> rows = io::readTextRows(file, io::Delimiter::kComma);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const io::TextRow& row = rows[i];
    if (isHeader(row, i)) continue;
    io::requireFieldCount(row, file, 2, 3);
    const bool framed = row.fields.size() == 3;
    const std::size_t id_field = framed ? 1 : 0;
    IdClass value;
    value.label = row.fields[id_field + 1];
    value.class_id = classOfLabel(value.label, taxonomy, row.at(file, "label"));
    const int id = parseInstanceId(row, file, id_field);
    if (framed) {
      const TimeNs t_ns = io::parseIntegerNs(row.fields[0], row.at(file, "t_ns"));
      insertClass(table.per_frame, std::make_pair(t_ns, id), std::move(value), row.at(file, "id"));
    } else {
      insertClass(table.every_frame, id, std::move(value), row.at(file, "id"));
    }
  }
  return table;
}

Segmentation segmentationFromIdImage(const cv::Mat& ids, TimeNs t_ns, const IdClassTable& table,
                                     const fs::path& file) {
  Segmentation segmentation;
  segmentation.ids = ids.clone();
  for (const auto& [id, pixel] : idsIn(ids)) {
    const IdClass* found = table.find(t_ns, id);
    if (found == nullptr) {
      throw InputError(InputLocation{file},
                       fmt::format("id {} (pixel ({}, {})) is not in the class table {}", id,
                                   pixel.x, pixel.y, table.file.string()));
    }
    if (found->class_id == sensors::kInstanceClassBackground) {
      segmentation.ids.setTo(0, ids == id);
      continue;
    }
    Instance instance;
    instance.id = id;
    instance.class_id = found->class_id;
    instance.label = found->label;
    segmentation.instances.push_back(std::move(instance));
  }
  updateBoxesAndAreas(segmentation);
  return segmentation;
}

IdPngSegmenter::IdPngSegmenter(const SegmenterOptions& options)
    : has_right_(!options.id_png_folder_right.empty()), tracked_ids_(options.id_png_tracked_ids) {
  if (options.id_png_folder.empty()) {
    throw OptionError("semantics.id_png_folder", "dataset_format id_png needs the folder");
  }
  if (options.right_labels == "segment" && !has_right_) {
    throw OptionError("semantics.id_png_folder_right",
                      "right_labels segment needs the right image's folder");
  }
  if (options.right_labels == "auto" && tracked_ids_ && !has_right_) {
    throw OptionError("semantics.id_png_folder_right",
                      "tracked ids segment the right image under right_labels auto: give its "
                      "folder, or set right_labels: left");
  }
  const std::string folders[2] = {options.id_png_folder, options.id_png_folder_right};
  for (int camera = 0; camera < (has_right_ ? 2 : 1); ++camera) {
    Folder& folder = folders_[camera];
    folder.images = folders[camera];
    if (!fs::is_directory(folder.images)) {
      throw InputError(InputLocation{folder.images}, "instance-id image folder does not exist");
    }
    folder.classes =
        readIdClassTable(tableOf(options.id_png_classes, folder.images), options.taxonomy);
  }
}

cv::Mat IdPngSegmenter::readIdImage(const fs::path& file, cv::Size image_size) const {
  if (!fs::is_regular_file(file)) {
    throw InputError(InputLocation{file},
                     "no instance-id image for this frame (each frame needs "
                     "<t_ns>.png, the frame's time in nanoseconds)");
  }
  const cv::Mat ids = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
  if (ids.empty()) throw InputError(InputLocation{file}, "cannot read the instance-id image");
  if (ids.depth() != CV_16U || ids.channels() != 1) {
    throw InputError(InputLocation{file},
                     fmt::format("is a {}-bit image with {} channel(s); expected a 16-bit "
                                 "single-channel PNG of instance ids",
                                 8 * CV_ELEM_SIZE1(ids.type()), ids.channels()));
  }
  if (ids.size() != image_size) {
    throw InputError(InputLocation{file},
                     fmt::format("instance-id image is {}x{}, the camera image {}x{}", ids.cols,
                                 ids.rows, image_size.width, image_size.height));
  }
  return ids;
}

Segmentation IdPngSegmenter::segment(const cv::Mat& image, TimeNs t_ns, int camera) {
  if (camera != 0 && !has_right_) {
    throw OptionError("semantics.id_png_folder_right", "the right image has no id folder");
  }
  const Folder& folder = folders_[camera == 0 ? 0 : 1];
  const fs::path file = folder.images / fmt::format("{}.png", t_ns);
  return segmentationFromIdImage(readIdImage(file, image.size()), t_ns, folder.classes, file);
}

std::string IdPngSegmenter::description() const {
  return fmt::format("dataset (instance-id PNGs of {}{})", folders_[0].images.string(),
                     has_right_ ? " and " + folders_[1].images.string() : std::string());
}

}  // namespace superdyna::semantics

#include "superdyna/semantics/dataset_segmenter.h"

#include <fmt/format.h>

#include <cmath>
#include <opencv2/imgcodecs.hpp>

#include "superdyna/core/error.h"
#include "superdyna/io/text_table.h"

namespace superdyna::semantics {

namespace fs = std::filesystem;

namespace {

/// Whether the first row is a header line ("id,r,g,b", "id, name").
bool isHeader(const io::TextRow& row, std::size_t index) {
  return index == 0 && !row.fields.empty() && row.fields[0] == "id";
}

int parseId(const io::TextRow& row, const fs::path& file, std::size_t field, const char* name,
            int max) {
  const double value = io::parseFiniteDouble(row.fields[field], row.at(file, name));
  if (value != std::round(value) || value < 0 || value > max) {
    throw InputError(row.at(file, name), fmt::format("expected an integer in [0, {}]", max));
  }
  return static_cast<int>(value);
}

fs::path tableOr(const std::string& option, const fs::path& fallback) {
  return option.empty() ? fallback : fs::path(option);
}

}  // namespace

std::map<std::uint32_t, int> readColourTable(const fs::path& file) {
  std::map<std::uint32_t, int> table;
  const std::vector<io::TextRow> rows = io::readTextRows(file, io::Delimiter::kComma);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const io::TextRow& row = rows[i];
    if (isHeader(row, i)) continue;
    io::requireFieldCount(row, file, 4, 4);
    const int id = parseId(row, file, 0, "id", 65535);
    const std::uint32_t colour =
        packRgb(parseId(row, file, 1, "r", 255), parseId(row, file, 2, "g", 255),
                parseId(row, file, 3, "b", 255));
    const auto [it, inserted] = table.emplace(colour, id);
    if (!inserted) {
      throw InputError(row.at(file, "r"),
                       fmt::format("colour of id {} is also the colour of id {}", id, it->second));
    }
  }
  if (table.empty()) throw InputError(InputLocation{file}, "no colours listed");
  return table;
}

ColourTables readColourTables(const SegmenterOptions& options, const fs::path& calibration) {
  const fs::path folder =
      fs::is_regular_file(calibration) ? calibration.parent_path() : calibration;
  const fs::path tables = fs::exists(folder / "mav0") ? folder / "mav0" : folder;
  ColourTables out;
  out.object_of_colour =
      readColourTable(tableOr(options.color_table, tables / "segmentation_colors.csv"));
  out.classes = options.movable_ids.empty() ? io::readInstanceClasses(tables / "instances.csv")
                                            : readMovableIds(options.movable_ids);
  if (out.classes.empty()) {
    throw InputError(InputLocation{tables / "instances.csv"},
                     "no movable objects: give semantics.movable_ids (VIODE: "
                     "vehicle_ids_<scene>.txt)");
  }
  return out;
}

std::map<int, int> readMovableIds(const fs::path& file) {
  std::map<int, int> classes;
  const std::vector<io::TextRow> rows = io::readTextRows(file, io::Delimiter::kComma);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const io::TextRow& row = rows[i];
    if (isHeader(row, i)) continue;
    io::requireFieldCount(row, file, 1, 2);
    const int id = parseId(row, file, 0, "id", 65535);
    if (id == 0) throw InputError(row.at(file, "id"), "id 0 is the background");
    classes[id] = sensors::kInstanceClassVehicle;
  }
  return classes;
}

Segmentation segmentationFromIds(cv::Mat ids, const std::map<int, int>& classes) {
  Segmentation segmentation;
  segmentation.ids = std::move(ids);
  for (const auto& [id, class_id] : classes) {
    Instance instance;
    instance.id = id;
    instance.class_id = class_id;
    instance.label = std::string(sensors::instanceClassName(class_id));
    segmentation.instances.push_back(std::move(instance));
  }
  updateBoxesAndAreas(segmentation);  // drops the instances not in this image
  return segmentation;
}

Segmentation segmentationFromColours(const cv::Mat& bgr,
                                     const std::map<std::uint32_t, int>& object_of_colour,
                                     const std::map<int, int>& classes, const fs::path& file) {
  if (bgr.type() != CV_8UC3) {
    throw InputError(InputLocation{file}, "expected an 8-bit colour segmentation image");
  }
  cv::Mat ids(bgr.size(), CV_16UC1, cv::Scalar(0));
  // Consecutive pixels mostly share their colour: look a colour up only when it changes.
  std::uint32_t last_colour = 0xFFFFFFFFu;
  std::uint16_t last_id = 0;
  for (int r = 0; r < bgr.rows; ++r) {
    const auto* in = bgr.ptr<cv::Vec3b>(r);
    auto* out = ids.ptr<std::uint16_t>(r);
    for (int c = 0; c < bgr.cols; ++c) {
      const std::uint32_t colour = packRgb(in[c][2], in[c][1], in[c][0]);
      if (colour != last_colour) {
        const auto it = object_of_colour.find(colour);
        if (it == object_of_colour.end()) {
          throw InputError(InputLocation{file},
                           fmt::format("pixel ({}, {}) has colour rgb({}, {}, {}), which the "
                                       "colour table does not list",
                                       c, r, in[c][2], in[c][1], in[c][0]));
        }
        last_colour = colour;
        last_id = classes.contains(it->second) ? static_cast<std::uint16_t>(it->second) : 0;
      }
      out[c] = last_id;
    }
  }
  return segmentationFromIds(std::move(ids), classes);
}

DatasetSegmenter::DatasetSegmenter(const fs::path& dataset, const SegmenterOptions& options)
    : dataset_(io::EurocDataset::open(dataset)), colour_(options.dataset_format == "color") {
  for (const io::ImageRef& image : dataset_.monoFrames())
    images_[0][image.t_ns] = image.path;
  for (const io::StereoFrameRef& frame : dataset_.stereoFrames())
    images_[1][frame.t_ns] = frame.cam1;
  if (colour_) {
    const fs::path first = dataset_.monoFrames().front().path;
    const fs::path folder = first.parent_path().parent_path() / "segmentation";
    if (!fs::is_directory(folder)) {
      throw InputError(InputLocation{folder},
                       "colour segmentation requested but the folder does not exist (simulate "
                       "with --semantic-color)");
    }
    ColourTables tables = readColourTables(options, dataset_.root());
    object_of_colour_ = std::move(tables.object_of_colour);
    classes_ = std::move(tables.classes);
    return;
  }
  if (!dataset_.hasInstanceMasks()) {
    throw InputError(InputLocation(dataset_.root() / "instances.csv"),
                     "instance masks requested but the dataset has no instances.csv and "
                     "cam0/mask/ (only simulated sequences have them)");
  }
  classes_ = dataset_.instanceClasses();
}

const fs::path& DatasetSegmenter::imageAt(TimeNs t_ns, int camera) const {
  const auto& images = images_[camera == 0 ? 0 : 1];
  const auto it = images.find(t_ns);
  if (it == images.end()) {
    throw InputError(InputLocation{dataset_.root() / fmt::format("cam{}", camera)},
                     fmt::format("no image at t = {} ns to take the segmentation of", t_ns));
  }
  return it->second;
}

Segmentation DatasetSegmenter::segment(const cv::Mat& image, TimeNs t_ns, int camera) {
  const fs::path& source = imageAt(t_ns, camera);
  if (!colour_)
    return segmentationFromIds(dataset_.loadInstanceMask(source, image.size()), classes_);
  const fs::path file = source.parent_path().parent_path() / "segmentation" / source.filename();
  const cv::Mat bgr = cv::imread(file.string(), cv::IMREAD_COLOR);
  if (bgr.empty()) throw InputError(InputLocation{file}, "cannot read the segmentation image");
  if (bgr.size() != image.size()) {
    throw InputError(InputLocation{file}, fmt::format("segmentation is {}x{}, the image {}x{}",
                                                      bgr.cols, bgr.rows, image.cols, image.rows));
  }
  return segmentationFromColours(bgr, object_of_colour_, classes_, file);
}

std::string DatasetSegmenter::description() const {
  return colour_ ? "dataset (colour segmentation images)" : "dataset (instance masks)";
}

}  // namespace superdyna::semantics

#include "superdyna/bag/bag_segmenter.h"

#include <fmt/format.h>

#include "superdyna/core/error.h"
#include "superdyna/semantics/dataset_segmenter.h"

namespace superdyna::bag {

namespace fs = std::filesystem;

namespace {

constexpr const char* kSegmentationTopics[2] = {"/cam0/segmentation", "/cam1/segmentation"};

}  // namespace

BagColourSegmenter::BagColourSegmenter(const fs::path& bag, const std::string topics[2],
                                       std::map<std::uint32_t, int> object_of_colour,
                                       std::map<int, int> classes)
    : reader_(RosbagReader::open(bag)),
      object_of_colour_(std::move(object_of_colour)),
      classes_(std::move(classes)) {
  for (int camera = 0; camera < 2; ++camera) {
    topics_[camera] = topics[camera];
    if (!topics_[camera].empty()) {
      streams_[camera] = std::make_unique<BagImageStream>(reader_, topics_[camera]);
    }
  }
}

BagColourSegmenter::~BagColourSegmenter() = default;

semantics::Segmentation BagColourSegmenter::segment(const cv::Mat& /*image*/, TimeNs t_ns,
                                                    int camera) {
  BagImageStream* stream = streams_[camera == 0 ? 0 : 1].get();
  const std::string& topic = topics_[camera == 0 ? 0 : 1];
  if (!stream) {
    throw InputError(InputLocation{reader_.path()},
                     fmt::format("no segmentation topic for camera {}", camera));
  }
  while (const std::optional<BagImage> image = stream->next()) {
    if (image->t_ns < t_ns) continue;
    if (image->t_ns > t_ns) break;
    if (image->image.type() != CV_8UC3) {
      throw InputError(
          InputLocation{reader_.path()},
          fmt::format("topic {}: the segmentation at {} ns is not a colour image", topic, t_ns));
    }
    return semantics::segmentationFromColours(
        image->image, object_of_colour_, classes_,
        fs::path(fmt::format("{}:{}@{}", reader_.path().string(), topic, t_ns)));
  }
  throw InputError(InputLocation{reader_.path()},
                   fmt::format("topic {}: no segmentation image stamped {} ns", topic, t_ns));
}

std::unique_ptr<semantics::Segmenter> makeBagSegmenter(const semantics::SegmenterOptions& options,
                                                       const fs::path& bag,
                                                       const fs::path& calibration) {
  options.validate();
  if (options.segmenter != "dataset") return semantics::makeSegmenter(options, calibration);
  if (options.dataset_format != "color") {
    throw OptionError("semantics.dataset_format",
                      fmt::format("a bag carries colour segmentation topics: use color, not {}",
                                  options.dataset_format));
  }
  semantics::ColourTables tables = semantics::readColourTables(options, calibration);
  const std::string topics[2] = {kSegmentationTopics[0],
                                 options.right_labels == "left" ? "" : kSegmentationTopics[1]};
  return semantics::withPerturbation(
      options, std::make_unique<BagColourSegmenter>(bag, topics, std::move(tables.object_of_colour),
                                                    std::move(tables.classes)));
}

}  // namespace superdyna::bag

#pragma once
// A bag's colour segmentation topics (VIODE: /cam0/segmentation, /cam1/segmentation; one colour
// per object) as the dataset backend's colour format (semantics/dataset_segmenter.h) reads them
// from a folder: the segmentation image of the asked time and camera, colours -> object ids
// through a colour table, and the objects of a movable-id list (or of a simulator's
// instances.csv) are the instances with their object id as instance id.

#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "superdyna/bag/rosbag_reader.h"
#include "superdyna/semantics/segmenter.h"

namespace superdyna::bag {

class BagColourSegmenter : public semantics::Segmenter {
 public:
  /// `topics`: the segmentation topic of camera 0 and of camera 1 ("" = none). `classes`: object
  /// id -> class of the movable objects. InputError naming the bag when a topic is missing.
  BagColourSegmenter(const std::filesystem::path& bag, const std::string topics[2],
                     std::map<std::uint32_t, int> object_of_colour, std::map<int, int> classes);
  ~BagColourSegmenter() override;

  /// Frames are asked in increasing time: each camera's stream moves forward to t_ns. InputError
  /// naming the bag and topic when it has no image of that stamp.
  semantics::Segmentation segment(const cv::Mat& image, TimeNs t_ns, int camera) override;
  std::string description() const override { return "dataset (bag colour segmentation topics)"; }
  bool idsNameObjects() const override { return true; }

 private:
  RosbagReader reader_;
  std::string topics_[2];
  std::unique_ptr<BagImageStream> streams_[2];
  std::map<std::uint32_t, int> object_of_colour_;
  std::map<int, int> classes_;
};

/// The segmenter `options` choose for a bag whose sensors the folder `calibration` describes:
/// the dataset backend reads the bag's segmentation topics ("color" format only; the colour table
/// and movable ids from the options, by default the calibration folder's (or its mav0's)
/// segmentation_colors.csv and instances.csv); networks as semantics::makeSegmenter; nullptr for
/// "none". OptionError for a dataset format a bag does not carry.
std::unique_ptr<semantics::Segmenter> makeBagSegmenter(const semantics::SegmenterOptions& options,
                                                       const std::filesystem::path& bag,
                                                       const std::filesystem::path& calibration);

}  // namespace superdyna::bag

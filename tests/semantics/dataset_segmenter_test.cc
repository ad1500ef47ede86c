// The dataset backend: the simulator's instance masks, and VIODE-style colour segmentation images
// decoded through a colour table and a movable-id list.

#include "superdyna/semantics/dataset_segmenter.h"

#include <gtest/gtest.h>

#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "superdyna/features/orb_extractor.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/tracking/front_end.h"
#include "support/generated_sequence.h"
#include "support/test_support.h"

namespace superdyna::semantics {
namespace {

namespace fs = std::filesystem;

/// A 1.5 s street with moving and parked cars and people, with colour segmentation images.
const fs::path& colourStreet() {
  sim::SimulationOptions options =
      test::flightOptions(1.5, sim::SceneType::kStreet, sim::DynamicLevel::kHigh, 11);
  options.landmark_count = 0;
  options.semantic_color = true;
  return test::generatedSequence("semantics_colour_street", options);
}

SegmenterOptions datasetOptions(const std::string& format) {
  SegmenterOptions options;
  options.segmenter = "dataset";
  options.dataset_format = format;
  return options;
}

TEST(DatasetSegmenter, ColourImagesGiveTheKeypointLabelsOfTheInstanceMasks) {
  const fs::path& path = colourStreet();
  const auto masks_backend = makeSegmenter(datasetOptions("masks"), path);
  const auto colour_backend = makeSegmenter(datasetOptions("color"), path);
  ASSERT_TRUE(masks_backend && colour_backend);
  EXPECT_TRUE(colour_backend->idsNameObjects());
  const auto source = io::openDataset(io::DatasetKind::kEuroc, path, {.inertial = false});
  features::FeatureOptions feature_options;
  const auto extractor = features::makeExtractor(feature_options);
  int frames = 0, keypoints = 0, on_vehicles = 0, on_pedestrians = 0;
  while (const std::optional<sensors::FrameBundle> bundle = source->next()) {
    const auto segment = [&](Segmenter& segmenter) {
      return toInstanceMasks(segmenter.segment(bundle->image0, bundle->t_ns, 0),
                             segmenter.segment(bundle->image1, bundle->t_ns, 1),
                             segmenter.idsNameObjects());
    };
    const sensors::InstanceMasks from_masks = segment(*masks_backend);
    const sensors::InstanceMasks from_colours = segment(*colour_backend);
    // Pixel for pixel the same instances in both images.
    ASSERT_EQ(cv::countNonZero(from_masks.cam0 != from_colours.cam0), 0) << bundle->index;
    ASSERT_EQ(cv::countNonZero(from_masks.cam1 != from_colours.cam1), 0) << bundle->index;
    // And so the same label on every keypoint.
    std::vector<features::Keypoint> a = extractor->extract(bundle->image0).keypoints;
    std::vector<features::Keypoint> b = a;
    tracking::labelKeypoints(from_masks.cam0, from_masks, a);
    tracking::labelKeypoints(from_colours.cam0, from_colours, b);
    for (std::size_t i = 0; i < a.size(); ++i) {
      ASSERT_EQ(a[i].instance_id, b[i].instance_id) << bundle->index << " keypoint " << i;
      ASSERT_EQ(a[i].class_id, b[i].class_id) << bundle->index << " keypoint " << i;
      on_vehicles += a[i].class_id == features::kClassVehicle;
      on_pedestrians += a[i].class_id == features::kClassPedestrian;
    }
    keypoints += static_cast<int>(a.size());
    ++frames;
  }
  std::cout << frames << " frames, " << keypoints << " keypoints: " << on_vehicles
            << " on vehicles, " << on_pedestrians << " on pedestrians, identical labels\n";
  EXPECT_EQ(frames, 31);
  EXPECT_GT(on_vehicles, 500);  // the comparison covers labelled keypoints, not only background
  EXPECT_GT(on_pedestrians, 50);
}

TEST(DatasetSegmenter, InstanceMasksKeepTheirIdsAndClasses) {
  const fs::path& path = colourStreet();
  const auto backend = makeSegmenter(datasetOptions("masks"), path);
  const auto source = io::openDataset(io::DatasetKind::kEuroc, path,
                                      {.inertial = false, .max_frames = 1, .instance_masks = true});
  const sensors::FrameBundle bundle = *source->next();
  const Segmentation segmentation = backend->segment(bundle.image0, bundle.t_ns, 0);
  // Today's reader path and the backend agree.
  EXPECT_EQ(cv::countNonZero(segmentation.ids != bundle.masks->cam0), 0);
  ASSERT_FALSE(segmentation.instances.empty());
  for (const Instance& instance : segmentation.instances) {
    EXPECT_EQ(instance.class_id, bundle.masks->classOf(instance.id));
    EXPECT_EQ(instance.label, sensors::instanceClassName(instance.class_id));
    EXPECT_EQ(instance.area_px, cv::countNonZero(segmentation.ids == instance.id));
    EXPECT_EQ(instance.box, cv::boundingRect(segmentation.ids == instance.id));
  }
}

TEST(DatasetSegmenter, ViodeTablesMapColoursToVehicleInstances) {
  SUPERDYNA_REQUIRE_SHARED(meta, "data/viode_meta");
  const std::map<std::uint32_t, int> colours = readColourTable(meta / "rgb_ids.txt");
  EXPECT_EQ(colours.size(), 255u);
  EXPECT_EQ(colours.at(packRgb(203, 174, 42)), 1);
  EXPECT_EQ(colours.at(packRgb(166, 221, 155)), 246);
  const std::map<int, int> movable = readMovableIds(meta / "vehicle_ids_city_day.txt");
  EXPECT_EQ(movable.size(), 13u);
  EXPECT_EQ(movable.at(241), sensors::kInstanceClassVehicle);
  EXPECT_EQ(movable.at(255), sensors::kInstanceClassVehicle);
  // A VIODE-like image: static object 1 everywhere, vehicle 246 in a 6x4 block.
  cv::Mat bgr(20, 30, CV_8UC3, cv::Scalar(42, 174, 203));
  bgr(cv::Rect(5, 8, 6, 4)).setTo(cv::Scalar(155, 221, 166));
  const Segmentation segmentation = segmentationFromColours(bgr, colours, movable, "image.png");
  ASSERT_EQ(segmentation.instances.size(), 1u);
  EXPECT_EQ(segmentation.instances[0].id, 246);
  EXPECT_EQ(segmentation.instances[0].class_id, sensors::kInstanceClassVehicle);
  EXPECT_EQ(segmentation.instances[0].area_px, 24);
  EXPECT_EQ(segmentation.instances[0].box, cv::Rect(5, 8, 6, 4));
  EXPECT_EQ(cv::countNonZero(segmentation.ids), 24);
  // A colour that is not in the table.
  bgr.at<cv::Vec3b>(3, 7) = cv::Vec3b(1, 2, 3);
  test::expectError([&] { segmentationFromColours(bgr, colours, movable, "image.png"); },
                    {"image.png", "pixel (7, 3)", "rgb(3, 2, 1)", "colour table"});
}

TEST(DatasetSegmenter, BadTablesAndMissingSegmentationAreErrorsNamingTheFile) {
  const test::ScratchDir dir("semantics_bad_tables");
  test::writeFile(dir / "colours.txt", "id,r,g,b\n1,10,20,30\n2,10,20,30\n");
  test::expectError([&] { readColourTable(dir / "colours.txt"); },
                    {"colours.txt:3 [r]", "also the colour of id 1"});
  test::writeFile(dir / "colours.txt", "id,r,g,b\n1,10,20,300\n");
  test::expectError([&] { readColourTable(dir / "colours.txt"); },
                    {"colours.txt:2 [b]", "[0, 255]"});
  test::writeFile(dir / "ids.txt", "id, name\n0, sky\n");
  test::expectError([&] { readMovableIds(dir / "ids.txt"); }, {"ids.txt:2 [id]", "background"});
  SUPERDYNA_REQUIRE_SHARED(euroc, "data/euroc/V1_01_easy_micro");
  test::expectError([&] { makeSegmenter(datasetOptions("color"), euroc); },
                    {"segmentation", "--semantic-color"});
  test::expectError([&] { makeSegmenter(datasetOptions("masks"), euroc); }, {"instances.csv"});
}

}  // namespace
}  // namespace superdyna::semantics

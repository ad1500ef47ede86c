// The System with a segmenter: keypoints are labelled with the segmenter's masks, the same labels
// as the reader's masks give for the dataset backend, and perturbed masks change them.

#include <gtest/gtest.h>

#include <iostream>

#include "superdyna/system/system.h"
#include "support/generated_sequence.h"

namespace superdyna::system {
namespace {

namespace fs = std::filesystem;

const fs::path& colourStreet() {
  sim::SimulationOptions options =
      test::flightOptions(1.0, sim::SceneType::kStreet, sim::DynamicLevel::kHigh, 5);
  options.landmark_count = 0;
  options.semantic_color = true;
  return test::generatedSequence("system_segmenter_street", options);
}

struct LabelledRun {
  Trajectory trajectory;
  long keypoints_on_objects = 0;  ///< Left keypoints with a class other than background.
  long stereo_cross_class = 0;
};

LabelledRun runWith(const semantics::SegmenterOptions& semantics, bool reader_masks) {
  const fs::path& path = colourStreet();
  const auto source = io::openDataset(io::DatasetKind::kEuroc, path,
                                      {.inertial = false, .instance_masks = reader_masks});
  SystemOptions options;
  options.mode = SensorMode::kStereo;
  options.semantics = semantics;
  System slam(options, source->camera0(), source->camera1(), source->imu(),
              semantics::makeSegmenter(semantics, path));
  LabelledRun run;
  slam.setFrontEndCallback([&](const io::FrameBundle& bundle, const tracking::Frame& frame) {
    EXPECT_TRUE(bundle.masks.has_value());
    for (const features::Keypoint& k : frame.features.keypoints)
      run.keypoints_on_objects += k.class_id != features::kClassBackground;
  });
  slam.run(*source);
  run.trajectory = slam.trajectory();
  run.stereo_cross_class = slam.timings().matches.stereo_cross_class;
  return run;
}

TEST(SystemSegmenter, DatasetBackendsLabelKeypointsAsTheReaderMasks) {
  const LabelledRun reader = runWith({}, true);
  semantics::SegmenterOptions options;
  options.segmenter = "dataset";
  const LabelledRun masks = runWith(options, false);
  options.dataset_format = "color";
  const LabelledRun colours = runWith(options, false);
  std::cout << "keypoints on objects: reader masks " << reader.keypoints_on_objects
            << ", dataset masks " << masks.keypoints_on_objects << ", colour images "
            << colours.keypoints_on_objects << "\n";
  EXPECT_GT(reader.keypoints_on_objects, 500);
  EXPECT_EQ(masks.keypoints_on_objects, reader.keypoints_on_objects);
  EXPECT_EQ(colours.keypoints_on_objects, reader.keypoints_on_objects);
  ASSERT_EQ(masks.trajectory.size(), reader.trajectory.size());
  for (std::size_t i = 0; i < reader.trajectory.size(); ++i) {
    EXPECT_EQ(masks.trajectory[i].T_w_x.t, reader.trajectory[i].T_w_x.t) << i;
    EXPECT_EQ(colours.trajectory[i].T_w_x.t, reader.trajectory[i].T_w_x.t) << i;
  }
}

TEST(SystemSegmenter, DilatedMasksLabelMoreKeypoints) {
  semantics::SegmenterOptions options;
  options.segmenter = "dataset";
  const LabelledRun exact = runWith(options, false);
  options.mask_dilate = 5;  // the paper's perturbation
  const LabelledRun dilated = runWith(options, false);
  options.mask_dilate = 0;
  options.mask_erode = 5;
  const LabelledRun eroded = runWith(options, false);
  std::cout << "keypoints on objects: exact " << exact.keypoints_on_objects << ", dilated 5x "
            << dilated.keypoints_on_objects << ", eroded 5x " << eroded.keypoints_on_objects
            << "\n";
  EXPECT_GT(dilated.keypoints_on_objects, exact.keypoints_on_objects * 11 / 10);
  EXPECT_LT(eroded.keypoints_on_objects, exact.keypoints_on_objects * 9 / 10);
}

}  // namespace
}  // namespace superdyna::system

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
  slam.setFrontEndCallback([&](const sensors::FrameBundle& bundle, const tracking::Frame& frame) {
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

/// Keypoints on objects (by the true masks) of the frames whose masks were propagated, and how
/// many of them the propagated masks, and the last segmented frame's masks left in place, label
/// with their true class; and the keypoints the propagated masks put on objects wrongly.
struct PropagationScore {
  long on_objects = 0;
  long propagated_right = 0;
  long stale_right = 0;
  long background = 0;        ///< Keypoints on the background (by the true masks).
  long propagated_false = 0;  ///< ... labelled movable by the propagated masks.
};

PropagationScore scorePropagation(int every_n_frames) {
  const fs::path& path = colourStreet();
  const auto source =
      io::openDataset(io::DatasetKind::kEuroc, path, {.inertial = false, .instance_masks = false});
  SystemOptions options;
  options.mode = SensorMode::kStereo;
  options.semantics.segmenter = "dataset";
  options.semantics.every_n_frames = every_n_frames;
  System slam(options, source->camera0(), source->camera1(), source->imu(),
              semantics::makeSegmenter(options.semantics, path));
  const std::unique_ptr<semantics::Segmenter> truth =
      semantics::makeSegmenter(options.semantics, path);
  PropagationScore score;
  cv::Mat last_segmented;
  slam.setFrontEndCallback([&](const sensors::FrameBundle& bundle, const tracking::Frame& frame) {
    const semantics::Segmentation exact = truth->segment(bundle.image0, bundle.t_ns, 0);
    const auto classAt = [](const semantics::Segmentation& s, const cv::Mat& ids,
                            const features::Keypoint& k) {
      const int id = ids.at<std::uint16_t>(static_cast<int>(std::lround(k.pixel.y())),
                                           static_cast<int>(std::lround(k.pixel.x())));
      const semantics::Instance* instance = s.find(id);
      return instance ? instance->class_id : features::kClassBackground;
    };
    if (bundle.index % static_cast<std::size_t>(every_n_frames) == 0) {
      last_segmented = exact.ids;
      return;
    }
    for (const features::Keypoint& k : frame.features.keypoints) {
      const int true_class = classAt(exact, exact.ids, k);
      if (true_class == features::kClassBackground) {
        ++score.background;
        score.propagated_false += k.class_id != features::kClassBackground;
        continue;
      }
      ++score.on_objects;
      score.propagated_right += k.class_id == true_class;
      score.stale_right += classAt(exact, last_segmented, k) == true_class;
    }
  });
  slam.run(*source);
  EXPECT_EQ(slam.timings().propagated_frames,
            slam.timings().frames - slam.timings().segmented_frames);
  return score;
}

TEST(SystemSegmenter, PropagatedMasksFollowTheObjectsBetweenSegmentedFrames) {
  const PropagationScore score = scorePropagation(3);
  std::cout << "propagated frames: " << score.on_objects << " keypoints on objects, "
            << score.propagated_right << " labelled right by the propagated masks, "
            << score.stale_right << " by the last segmented masks; " << score.propagated_false
            << " of " << score.background << " background keypoints labelled movable\n";
  ASSERT_GT(score.on_objects, 300);
  // Measured: 89 % right against 74 % with the masks left in place; 0.5 % false.
  EXPECT_GT(score.propagated_right, score.on_objects * 85 / 100);
  EXPECT_GT(score.propagated_right, score.stale_right + score.on_objects / 10);
  EXPECT_LT(score.propagated_false, score.background / 100);
}

/// The class of every left keypoint of every frame, frame by frame, segmenting one frame in 3.
std::vector<std::vector<int>> labelsSegmentingOneFrameIn3(bool deterministic,
                                                          std::size_t* segmented) {
  const fs::path& path = colourStreet();
  const auto source =
      io::openDataset(io::DatasetKind::kEuroc, path, {.inertial = false, .instance_masks = false});
  SystemOptions options;
  options.mode = SensorMode::kStereo;
  options.deterministic = deterministic;
  options.semantics.segmenter = "dataset";
  options.semantics.every_n_frames = 3;
  System slam(options, source->camera0(), source->camera1(), source->imu(),
              semantics::makeSegmenter(options.semantics, path));
  std::vector<std::vector<int>> labels;
  slam.setFrontEndCallback([&](const sensors::FrameBundle&, const tracking::Frame& frame) {
    std::vector<int>& classes = labels.emplace_back();
    for (const features::Keypoint& k : frame.features.keypoints)
      classes.push_back(k.class_id);
  });
  slam.run(*source);
  *segmented = slam.timings().segmented_frames;
  return labels;
}

TEST(SystemSegmenter, SegmentingAFrameAheadLabelsTheKeypointsAsTheSequentialPipeline) {
  // The concurrent pipeline reads a bundle ahead and starts segmenting a frame to be segmented
  // while the frame before it is built; the masks, and so the labels, are those of the sequential
  // pipeline, which segments each frame beside its own extraction.
  std::size_t sequential_segmented = 0, concurrent_segmented = 0;
  const auto sequential = labelsSegmentingOneFrameIn3(true, &sequential_segmented);
  const auto concurrent = labelsSegmentingOneFrameIn3(false, &concurrent_segmented);
  ASSERT_EQ(sequential.size(), 21u);  // 1 s at 20 Hz
  EXPECT_EQ(sequential_segmented, 7u);
  EXPECT_EQ(concurrent_segmented, 7u);
  ASSERT_EQ(concurrent.size(), sequential.size());
  long on_objects = 0;
  for (std::size_t i = 0; i < sequential.size(); ++i) {
    EXPECT_EQ(concurrent[i], sequential[i]) << "frame " << i;
    for (const int c : sequential[i])
      on_objects += c != features::kClassBackground;
  }
  EXPECT_GT(on_objects, 300);
}

}  // namespace
}  // namespace superdyna::system

// The yolo backend on the shared YOLOv8n-seg model: cars of the real KITTI excerpt, and the error
// of a missing model.

#include "superdyna/semantics/yolo_segmenter.h"

#include <gtest/gtest.h>

#include <iostream>
#include <opencv2/imgcodecs.hpp>

#include "superdyna/inference/model_files.h"
#include "support/test_support.h"

namespace superdyna::semantics {
namespace {

constexpr const char* kModel = "models/yolov8n-seg-int8.onnx";

TEST(YoloSegmenter, AMissingModelSaysWhereItLooked) {
  const test::ScratchDir dir("semantics_no_model");
  const test::ScopedEnv env(inference::kModelDirVariable, dir.path().string());
  YoloOptions options;
  options.model = "no-such-yolo-seg.onnx";
  test::expectError([&] { YoloSegmenter(options, Taxonomy{}); },
                    {"no-such-yolo-seg.onnx", "not found", (dir / "no-such-yolo-seg.onnx").string(),
                     "yolo export model=yolov8n-seg.pt format=onnx"});
}

TEST(YoloSegmenter, FindsTheParkedCarsOfTheKittiExcerpt) {
  SUPERDYNA_REQUIRE_SHARED(model, kModel);
  SUPERDYNA_REQUIRE_SHARED(kitti, "data/kitti/snippet_1/image_l");
  YoloOptions options;
  options.model = model.string();
  options.inference_threads = 1;
  YoloSegmenter segmenter(options, Taxonomy{});
  EXPECT_EQ(segmenter.inputSize(), cv::Size(320, 320));
  ASSERT_EQ(segmenter.labels().size(), 80u);
  EXPECT_EQ(segmenter.labels()[2], "car");
  // At 320x320 a 1226x370 frame shrinks to 320x97: the near cars are found, the far parked ones
  // need a larger input (scripts/resize_yolo_seg_onnx.py, README "Instance segmentation").
  const std::vector<std::pair<const char*, int>> frames = {
      {"000000.png", 1}, {"000008.png", 3}, {"000025.png", 1}};
  for (const auto& [frame, min_vehicles] : frames) {
    const cv::Mat image = cv::imread((kitti / frame).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(image.empty()) << frame;
    const Segmentation segmentation = segmenter.segment(image, 0, 0);
    int vehicles = 0, largest = 0;
    for (const Instance& instance : segmentation.instances) {
      EXPECT_GT(instance.score, options.score_threshold);
      EXPECT_GE(instance.area_px, options.min_area_px);
      EXPECT_EQ(instance.area_px, cv::countNonZero(segmentation.ids == instance.id));
      // The mask lies inside the detection box.
      EXPECT_EQ(cv::countNonZero(segmentation.ids(instance.box) == instance.id), instance.area_px);
      if (instance.class_id != sensors::kInstanceClassVehicle) continue;
      ++vehicles;
      largest = std::max(largest, instance.area_px);
    }
    std::cout << frame << ": " << vehicles << " vehicles (largest mask " << largest << " px) of "
              << segmentation.instances.size() << " instances\n";
    EXPECT_GE(vehicles, min_vehicles) << frame;
    EXPECT_GT(largest, 5000) << frame;  // the car beside the road: thousands of pixels
  }
}

}  // namespace
}  // namespace superdyna::semantics

// The yolo backend on the shared YOLOv8n-seg model: cars of the real KITTI excerpt, and the error
// of a missing model.

#include "superdyna/semantics/yolo_segmenter.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
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
  // need a larger input (scripts/resize_yolo_seg_onnx.py, docs/concepts/segmentation.md).
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

constexpr const char* kPython = "/usr/bin/python3";

bool havePythonOnnx() {
  return std::system((std::string(kPython) + " -c 'import onnx' >/dev/null 2>&1").c_str()) == 0;
}

/// Runs scripts/<script> with `arguments`.
void runScript(const std::string& script, const std::string& arguments) {
  const std::string command = std::string(kPython) + " " + SUPERDYNA_SOURCE_DIR + "/scripts/" +
                              script + " " + arguments + " >/dev/null";
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
}

Segmentation segmentFrame(const std::filesystem::path& model, const std::filesystem::path& image) {
  YoloOptions options;
  options.model = model.string();
  options.inference_threads = 1;
  return YoloSegmenter(options, Taxonomy{})
      .segment(cv::imread(image.string(), cv::IMREAD_GRAYSCALE), 0, 0);
}

int vehiclesOf(const Segmentation& segmentation) {
  return static_cast<int>(std::count_if(
      segmentation.instances.begin(), segmentation.instances.end(),
      [](const Instance& i) { return i.class_id == sensors::kInstanceClassVehicle; }));
}

double iouOf(const Segmentation& a, int id_a, const Segmentation& b, int id_b) {
  const cv::Mat in_a = a.ids == id_a, in_b = b.ids == id_b;
  return double(cv::countNonZero(in_a & in_b)) / cv::countNonZero(in_a | in_b);
}

TEST(YoloSegmenter, ScriptedFp32AndResizedModelsAgreeWithTheShippedOne) {
  SUPERDYNA_REQUIRE_SHARED(model, kModel);
  SUPERDYNA_REQUIRE_SHARED(kitti, "data/kitti/snippet_1/image_l");
  if (!havePythonOnnx()) {
    GTEST_SKIP() << "Debian's python3-onnx is not installed (apt-get install python3-onnx)";
  }
  const test::ScratchDir dir("semantics_scripted_models");
  const std::string in = model.string();
  runScript("dequantize_yolo_onnx.py", in + " " + (dir / "fp32.onnx").string());
  runScript("resize_yolo_seg_onnx.py", in + " " + (dir / "int8_320.onnx").string() + " 320");
  runScript("resize_yolo_seg_onnx.py", in + " " + (dir / "int8_640.onnx").string() + " 640");

  // Resizing to the model's own size regenerates its constants exactly: the same result.
  const Segmentation shipped = segmentFrame(model, kitti / "000008.png");
  EXPECT_EQ(cv::countNonZero(segmentFrame(dir / "int8_320.onnx", kitti / "000008.png").ids !=
                             shipped.ids),
            0);
  // The dequantised model finds the same instances with nearly the same masks.
  const Segmentation fp32 = segmentFrame(dir / "fp32.onnx", kitti / "000008.png");
  ASSERT_EQ(fp32.instances.size(), shipped.instances.size());
  for (std::size_t i = 0; i < fp32.instances.size(); ++i) {
    EXPECT_EQ(fp32.instances[i].label, shipped.instances[i].label);
    EXPECT_NEAR(fp32.instances[i].score, shipped.instances[i].score, 0.05);
    const double iou = iouOf(fp32, fp32.instances[i].id, shipped, shipped.instances[i].id);
    std::cout << "fp32 vs int8, " << fp32.instances[i].label << ": mask IoU " << iou << "\n";
    EXPECT_GT(iou, 0.85);
  }
  // At 640 the far parked cars of frame 40 appear; at 320 they are too small.
  const int at_320 = vehiclesOf(segmentFrame(model, kitti / "000040.png"));
  const int at_640 = vehiclesOf(segmentFrame(dir / "int8_640.onnx", kitti / "000040.png"));
  std::cout << "frame 40: " << at_320 << " vehicles at 320, " << at_640 << " at 640\n";
  EXPECT_EQ(at_320, 0);
  EXPECT_GE(at_640, 2);
}

}  // namespace
}  // namespace superdyna::semantics

// The maskrcnn backend on small generated graphs with the output contract of torchvision's Mask
// R-CNN export (tests/semantics/maskrcnn_contract_model.py, which also writes what a plain numpy
// decoding of them gives), the label list, and the errors of a missing model or a wrong contract.

#include "superdyna/semantics/maskrcnn_segmenter.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <map>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "superdyna/inference/model_files.h"
#include "superdyna/semantics/maskrcnn_decoder.h"
#include "support/test_support.h"

namespace superdyna::semantics {
namespace {

namespace fs = std::filesystem;

constexpr const char* kPython = "/usr/bin/python3";

bool havePythonOnnx() {
  return std::system((std::string(kPython) + " -c 'import onnx' >/dev/null 2>&1").c_str()) == 0;
}

/// The graphs and expected segmentations of maskrcnn_contract_model.py, written into `dir`.
void writeContractModels(const fs::path& dir) {
  const std::string command = std::string(kPython) + " " + SUPERDYNA_TEST_DIR +
                              "/maskrcnn_contract_model.py " + dir.string() + " >/dev/null";
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
}

/// The script's test image (B, G, R bytes).
cv::Mat contractImage() {
  cv::Mat bgr(48, 64, CV_8UC3);
  for (int y = 0; y < bgr.rows; ++y) {
    for (int x = 0; x < bgr.cols; ++x) {
      const bool dark = y >= 10 && y < 30 && x >= 40 && x < 52;
      bgr.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<std::uint8_t>((3 * x + 5 * y) % 256),
                                          static_cast<std::uint8_t>((7 * x + y) % 256),
                                          static_cast<std::uint8_t>(dark ? 100 : 230));
    }
  }
  return bgr;
}

/// An expected segmentation file of the script: "instance ..." lines, "ids", the id rows.
Segmentation readExpected(const fs::path& file, cv::Size size) {
  std::ifstream in(file);
  Segmentation expected;
  expected.ids = cv::Mat(size, CV_16UC1, cv::Scalar(0));
  std::string word;
  while (in >> word && word == "instance") {
    Instance instance;
    in >> instance.id >> instance.label >> instance.class_id >> instance.score >> instance.box.x >>
        instance.box.y >> instance.box.width >> instance.box.height >> instance.area_px;
    std::replace(instance.label.begin(), instance.label.end(), '_', ' ');
    expected.instances.push_back(instance);
  }
  EXPECT_EQ(word, "ids") << file;
  for (int y = 0; y < size.height; ++y) {
    for (int x = 0; x < size.width; ++x) {
      int id = -1;
      in >> id;
      expected.ids.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(id);
    }
  }
  EXPECT_TRUE(in) << file << " ends early";
  return expected;
}

Segmentation segmentWith(const fs::path& model, const cv::Mat& image) {
  MaskRcnnOptions options;
  options.model = model.string();
  options.inference_threads = 1;
  return MaskRcnnSegmenter(options, Taxonomy{}).segment(image, 0, 0);
}

void expectSameSegmentation(const Segmentation& actual, const Segmentation& expected) {
  ASSERT_EQ(actual.instances.size(), expected.instances.size());
  for (std::size_t i = 0; i < actual.instances.size(); ++i) {
    const Instance& a = actual.instances[i];
    const Instance& e = expected.instances[i];
    EXPECT_EQ(a.id, e.id) << i;
    EXPECT_EQ(a.label, e.label) << i;
    EXPECT_EQ(a.class_id, e.class_id) << i;
    EXPECT_FLOAT_EQ(a.score, e.score) << i;
    EXPECT_EQ(a.box, e.box) << i;
    EXPECT_EQ(a.area_px, e.area_px) << i;
    EXPECT_EQ(a.area_px, cv::countNonZero(actual.ids == a.id)) << i;
  }
  EXPECT_EQ(cv::countNonZero(actual.ids != expected.ids), 0);
}

TEST(MaskRcnnSegmenter, ImageAndBoxResolutionMasksDecodeAsTheNumpyReference) {
  if (!havePythonOnnx()) {
    GTEST_SKIP() << "Debian's python3-onnx is not installed (apt-get install python3-onnx)";
  }
  const test::ScratchDir dir("semantics_maskrcnn_contract");
  writeContractModels(dir.path());
  const cv::Mat image = contractImage();
  // [3, H, W] input, masks pasted at the image's size.
  const Segmentation from_image_masks = segmentWith(dir / "image_masks.onnx", image);
  const Segmentation expected_image = readExpected(dir / "image_masks.txt", image.size());
  expectSameSegmentation(from_image_masks, expected_image);
  // What the reference found: the car (best wanted score) took the person's overlap and part of
  // its own mask is dimmed by the dark red block; chair, "N/A", a low-scored truck and a tiny bus
  // were dropped.
  ASSERT_EQ(expected_image.instances.size(), 4u);
  EXPECT_EQ(expected_image.instances[0].label, "car");
  EXPECT_EQ(expected_image.instances[0].area_px, 562);
  EXPECT_EQ(expected_image.instances[1].label, "person");
  EXPECT_EQ(expected_image.instances[1].class_id, sensors::kInstanceClassPedestrian);
  EXPECT_EQ(expected_image.instances[1].area_px, 560);
  EXPECT_EQ(expected_image.instances[2].label, "motorcycle");
  EXPECT_EQ(expected_image.instances[3].box, cv::Rect(0, 28, 22, 20));
  // [1, 3, H, W] input, 14 x 14 masks spanning their boxes.
  const Segmentation from_box_masks = segmentWith(dir / "box_masks.onnx", image);
  const Segmentation expected_box = readExpected(dir / "box_masks.txt", image.size());
  expectSameSegmentation(from_box_masks, expected_box);
  ASSERT_EQ(expected_box.instances.size(), 4u);
  EXPECT_EQ(expected_box.instances[0].area_px, 795);
  // A grey image is replicated to RGB: its red channel is the grey value.
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  EXPECT_NO_THROW(segmentWith(dir / "image_masks.onnx", grey));
}

TEST(MaskRcnnSegmenter, AWrongContractNamesTheModelFileAndTheTensor) {
  if (!havePythonOnnx()) {
    GTEST_SKIP() << "Debian's python3-onnx is not installed (apt-get install python3-onnx)";
  }
  const test::ScratchDir dir("semantics_maskrcnn_wrong_contract");
  writeContractModels(dir.path());
  test::expectError([&] { segmentWith(dir / "no_masks.onnx", contractImage()); },
                    {(dir / "no_masks.onnx").string(), "torchvision Mask R-CNN",
                     "output 'masks' missing", "mask_probabilities"});
}

TEST(MaskRcnnSegmenter, AMissingModelSaysWhereItLookedAndHowToMakeOne) {
  const test::ScratchDir dir("semantics_no_maskrcnn");
  const test::ScopedEnv env(inference::kModelDirVariable, dir.path().string());
  MaskRcnnOptions options;
  options.model = "no-such-maskrcnn.onnx";
  test::expectError([&] { MaskRcnnSegmenter(options, Taxonomy{}); },
                    {"no-such-maskrcnn.onnx", "not found", (dir / "no-such-maskrcnn.onnx").string(),
                     "scripts/export_maskrcnn_onnx.py"});
}

TEST(MaskRcnnDecoder, LabelsAreTorchvisionCategoryIdsNotCocoNamesLines) {
  const std::vector<std::string>& categories = torchvisionCocoCategories();
  ASSERT_EQ(categories.size(), 91u);
  EXPECT_EQ(categories[0], "__background__");
  EXPECT_EQ(categories[1], "person");
  EXPECT_EQ(categories[3], "car");
  EXPECT_EQ(categories[8], "truck");
  EXPECT_EQ(categories[90], "toothbrush");
  std::vector<int> gaps;
  for (std::size_t i = 0; i < categories.size(); ++i)
    if (categories[i] == "N/A") gaps.push_back(static_cast<int>(i));
  EXPECT_EQ(gaps, (std::vector<int>{12, 26, 29, 30, 45, 66, 68, 69, 71, 83}));

  // The 80 named categories are coco.names' lines in order (darknet spells six of them
  // differently), but at other indices: line 2 is "car" (label 3), line 79 "toothbrush" (90).
  SUPERDYNA_REQUIRE_SHARED(names_file, "models/coco.names");
  std::ifstream in(names_file);
  std::vector<std::string> names;
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) names.push_back(line);
  ASSERT_EQ(names.size(), 80u);
  const std::map<std::string, std::string> darknet = {
      {"motorbike", "motorcycle"},     {"aeroplane", "airplane"},       {"sofa", "couch"},
      {"pottedplant", "potted plant"}, {"diningtable", "dining table"}, {"tvmonitor", "tv"}};
  std::size_t line = 0;
  for (std::size_t label = 1; label < categories.size(); ++label) {
    if (categories[label] == "N/A") continue;
    ASSERT_LT(line, names.size());
    const auto alias = darknet.find(names[line]);
    EXPECT_EQ(alias == darknet.end() ? names[line] : alias->second, categories[label]) << label;
    ++line;
  }
  EXPECT_EQ(line, 80u);
}

TEST(MaskRcnnDecoder, ALabelOutsideTheListIsAnError) {
  const float boxes[] = {1, 1, 9, 9};
  const float labels[] = {91};
  const float scores[] = {0.9f};
  std::vector<float> masks(10 * 10, 1.0f);
  MaskRcnnOutputs outputs;
  outputs.detections = 1;
  outputs.boxes = boxes;
  outputs.labels = labels;
  outputs.scores = scores;
  outputs.masks = masks.data();
  outputs.mask_h = outputs.mask_w = 10;
  test::expectError(
      [&] {
        decodeMaskRcnn(outputs, {10, 10}, Taxonomy{}, MaskRcnnOptions{});
      },
      {"label 91", "torchvision's COCO list (0 to 90)"});
}

TEST(MaskRcnnDecoder, TheTaxonomyChoosesTheInstancesAndTheMinimumAreaDropsSmallOnes) {
  // One 10x10 image-resolution mask, a dog: background by default, an instance when listed.
  const float boxes[] = {0, 0, 10, 10};
  const float labels[] = {18};
  const float scores[] = {0.8f};
  std::vector<float> masks(10 * 10, 0.0f);
  for (int y = 2; y < 8; ++y)
    for (int x = 3; x < 9; ++x)
      masks[static_cast<std::size_t>(y * 10 + x)] = 0.75f;
  MaskRcnnOutputs outputs;
  outputs.detections = 1;
  outputs.boxes = boxes;
  outputs.labels = labels;
  outputs.scores = scores;
  outputs.masks = masks.data();
  outputs.mask_h = outputs.mask_w = 10;
  MaskRcnnOptions options;
  options.min_area_px = 36;
  EXPECT_TRUE(decodeMaskRcnn(outputs, {10, 10}, Taxonomy{}, options).instances.empty());
  Taxonomy with_dogs;
  with_dogs.other_movable = "dog";
  const Segmentation dogs = decodeMaskRcnn(outputs, {10, 10}, with_dogs, options);
  ASSERT_EQ(dogs.instances.size(), 1u);
  EXPECT_EQ(dogs.instances[0].class_id, sensors::kInstanceClassOtherMovable);
  EXPECT_EQ(dogs.instances[0].area_px, 36);
  EXPECT_EQ(dogs.instances[0].box, cv::Rect(0, 0, 10, 10));
  options.min_area_px = 37;
  EXPECT_TRUE(decodeMaskRcnn(outputs, {10, 10}, with_dogs, options).instances.empty());
}

}  // namespace
}  // namespace superdyna::semantics

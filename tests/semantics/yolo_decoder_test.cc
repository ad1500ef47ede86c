// The YOLOv8-seg decoding against its numpy reference (yolo_reference.py): the same fixed network
// outputs give the same letterbox, instances (label, class, score, box, area) and id image.

#include "superdyna/semantics/yolo_decoder.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "superdyna/core/error.h"

namespace superdyna::semantics {
namespace {

/// The inputs and expected results written by yolo_reference.py.
struct Reference {
  cv::Size image, input;
  double scale = 0;
  int left = 0, top = 0;
  cv::Size scaled;
  std::vector<std::string> labels;
  YoloOptions options;
  int channels = 0, anchors = 0, masks = 0, proto_h = 0, proto_w = 0;
  std::vector<float> output0, protos;
  std::vector<Instance> instances;
  cv::Mat ids;
};

void expectWord(std::istream& in, const std::string& word) {
  std::string read;
  in >> read;
  ASSERT_EQ(read, word);
}

std::vector<float> readFloats(std::istream& in, std::size_t n) {
  std::vector<float> values(n);
  for (float& v : values)
    in >> v;
  return values;
}

Reference readReference() {
  std::ifstream in(std::string(SUPERDYNA_TEST_DIR) + "/yolo_reference_data.txt");
  EXPECT_TRUE(in.good()) << "yolo_reference_data.txt missing";
  std::string comment;
  std::getline(in, comment);
  Reference r;
  expectWord(in, "image");
  in >> r.image.width >> r.image.height;
  expectWord(in, "input");
  in >> r.input.width >> r.input.height;
  expectWord(in, "letterbox");
  in >> r.scale >> r.left >> r.top >> r.scaled.width >> r.scaled.height;
  expectWord(in, "labels");
  for (int i = 0; i < 4; ++i) {
    std::string label;
    in >> label;
    r.labels.push_back(label);
  }
  expectWord(in, "options");
  in >> r.options.score_threshold >> r.options.nms_iou >> r.options.mask_threshold >>
      r.options.min_area_px >> r.options.max_detections;
  expectWord(in, "output0");
  in >> r.channels >> r.anchors;
  r.output0 = readFloats(in, static_cast<std::size_t>(r.channels * r.anchors));
  expectWord(in, "protos");
  in >> r.masks >> r.proto_h >> r.proto_w;
  r.protos = readFloats(in, static_cast<std::size_t>(r.masks * r.proto_h * r.proto_w));
  expectWord(in, "instances");
  int count = 0;
  in >> count;
  for (int i = 0; i < count; ++i) {
    Instance instance;
    in >> instance.id >> instance.label >> instance.class_id >> instance.score >> instance.box.x >>
        instance.box.y >> instance.box.width >> instance.box.height >> instance.area_px;
    r.instances.push_back(instance);
  }
  expectWord(in, "ids");
  r.ids = cv::Mat(r.image, CV_16UC1);
  for (int y = 0; y < r.image.height; ++y)
    for (int x = 0; x < r.image.width; ++x) {
      int id = 0;
      in >> id;
      r.ids.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(id);
    }
  EXPECT_FALSE(in.fail()) << "yolo_reference_data.txt is truncated";
  return r;
}

TEST(YoloDecoder, LetterboxEqualsTheReference) {
  const Reference r = readReference();
  const Letterbox letterbox = letterboxFor(r.image, r.input);
  EXPECT_EQ(letterbox.scale, r.scale);
  EXPECT_EQ(letterbox.left, r.left);
  EXPECT_EQ(letterbox.top, r.top);
  EXPECT_EQ(letterbox.scaled, r.scaled);
  // Ultralytics' rounding on a KITTI frame at 320: 1226x370 -> 320x97, 111 rows of padding above.
  const Letterbox kitti = letterboxFor({1226, 370}, {320, 320});
  EXPECT_EQ(kitti.scaled, cv::Size(320, 97));
  EXPECT_EQ(kitti.top, 111);
  EXPECT_EQ(kitti.left, 0);
}

TEST(YoloDecoder, SegmentationEqualsTheNumpyReference) {
  const Reference r = readReference();
  YoloOutputs outputs{r.output0.data(), r.channels, r.anchors, r.protos.data(),
                      r.masks,          r.proto_h,  r.proto_w};
  const Segmentation segmentation = decodeSegmentation(outputs, letterboxFor(r.image, r.input),
                                                       r.image, r.labels, Taxonomy{}, r.options);
  // The reference keeps 4 of 9 candidates: one car suppressed by NMS, the dog unwanted, a tiny
  // car below the minimum area, a person exactly at the score threshold.
  ASSERT_EQ(r.instances.size(), 4u);
  ASSERT_EQ(segmentation.instances.size(), r.instances.size());
  for (std::size_t i = 0; i < r.instances.size(); ++i) {
    const Instance& got = segmentation.instances[i];
    const Instance& want = r.instances[i];
    EXPECT_EQ(got.id, want.id);
    EXPECT_EQ(got.label, want.label);
    EXPECT_EQ(got.class_id, want.class_id);
    EXPECT_EQ(got.score, want.score);
    EXPECT_EQ(got.box, want.box) << got.label << " " << got.id;
    EXPECT_EQ(got.area_px, want.area_px) << got.label << " " << got.id;
  }
  EXPECT_EQ(cv::countNonZero(segmentation.ids != r.ids), 0);
  EXPECT_EQ(cv::countNonZero(segmentation.ids), 246 + 75 + 333 + 139);
}

TEST(YoloDecoder, TaxonomyDecidesWhichClassesAreInstances) {
  const Reference r = readReference();
  YoloOutputs outputs{r.output0.data(), r.channels, r.anchors, r.protos.data(),
                      r.masks,          r.proto_h,  r.proto_w};
  Taxonomy taxonomy;
  taxonomy.other_movable = "dog";
  const Segmentation with_dog = decodeSegmentation(outputs, letterboxFor(r.image, r.input), r.image,
                                                   r.labels, taxonomy, r.options);
  ASSERT_EQ(with_dog.instances.size(), 5u);
  EXPECT_EQ(with_dog.instances[0].label, "dog");  // the best score, 0.95
  EXPECT_EQ(with_dog.instances[0].class_id, sensors::kInstanceClassOtherMovable);
  taxonomy.vehicle = "";
  const Segmentation no_cars = decodeSegmentation(outputs, letterboxFor(r.image, r.input), r.image,
                                                  r.labels, taxonomy, r.options);
  for (const Instance& instance : no_cars.instances)
    EXPECT_NE(instance.label, "car");
  taxonomy.pedestrian = "person,dog";
  EXPECT_THROW(taxonomy.validate(), OptionError);
}

TEST(YoloDecoder, UltralyticsNamesMetadataParses) {
  const std::vector<std::string> names = parseUltralyticsNames(
      "{0: 'person', 1: 'bicycle', 9: 'traffic light', 10: \"fire hydrant\"}");
  EXPECT_EQ(names,
            (std::vector<std::string>{"person", "bicycle", "traffic light", "fire hydrant"}));
  EXPECT_TRUE(parseUltralyticsNames("{0: 'person").empty());
}

}  // namespace
}  // namespace superdyna::semantics

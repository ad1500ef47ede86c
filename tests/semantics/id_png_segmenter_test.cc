// The dataset backend's id_png format: folders of user-made 16-bit instance-id PNGs with a class
// table, written by the tests into scratch folders.

#include "superdyna/semantics/id_png_segmenter.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "support/test_support.h"

namespace superdyna::semantics {
namespace {

namespace fs = std::filesystem;

constexpr TimeNs kFirst = 1403636579763555584;
constexpr TimeNs kSecond = 1403636579813555456;

/// A 40x30 id image: id 3 in a 10x5 block, id 7 in a 4x6 block, id 9 in a 2x2 block.
cv::Mat idImage() {
  cv::Mat ids(30, 40, CV_16UC1, cv::Scalar(0));
  ids(cv::Rect(2, 3, 10, 5)).setTo(3);
  ids(cv::Rect(20, 10, 4, 6)).setTo(7);
  ids(cv::Rect(30, 25, 2, 2)).setTo(9);
  return ids;
}

void writePng(const fs::path& file, const cv::Mat& image) {
  ASSERT_TRUE(cv::imwrite(file.string(), image)) << file;
}

SegmenterOptions idPngOptions(const fs::path& left, const fs::path& right = {}) {
  SegmenterOptions options;
  options.segmenter = "dataset";
  options.dataset_format = "id_png";
  options.id_png_folder = left.string();
  options.id_png_folder_right = right.string();
  return options;
}

const cv::Mat kCameraImage(30, 40, CV_8UC1, cv::Scalar(128));

TEST(IdPngSegmenter, IdsKeepTheirValuesWithTheTableClasses) {
  const test::ScratchDir dir("semantics_id_png");
  fs::create_directories(dir / "left");
  writePng(dir / "left" / fmt::format("{}.png", kFirst), idImage());
  writePng(dir / "left" / fmt::format("{}.png", kSecond), idImage());
  // id 3 a COCO car, 7 a class name, 9 a chair (background); in the second frame id 7 is a
  // person (a per-image tool's ids).
  test::writeFile(dir / "left" / "classes.csv",
                  fmt::format("id,label\n3,car\n7,vehicle\n9,chair\n{},7,person\n", kSecond));
  const auto segmenter = makeSegmenter(idPngOptions(dir / "left"), "unused");
  ASSERT_TRUE(segmenter);
  EXPECT_FALSE(segmenter->idsNameObjects());
  const Segmentation first = segmenter->segment(kCameraImage, kFirst, 0);
  ASSERT_EQ(first.instances.size(), 2u);
  EXPECT_EQ(first.instances[0].id, 3);
  EXPECT_EQ(first.instances[0].label, "car");
  EXPECT_EQ(first.instances[0].class_id, sensors::kInstanceClassVehicle);
  EXPECT_EQ(first.instances[0].area_px, 50);
  EXPECT_EQ(first.instances[0].box, cv::Rect(2, 3, 10, 5));
  EXPECT_EQ(first.instances[1].id, 7);
  EXPECT_EQ(first.instances[1].label, "vehicle");
  EXPECT_EQ(first.instances[1].area_px, 24);
  EXPECT_EQ(first.instances[1].box, cv::Rect(20, 10, 4, 6));
  // The chair's pixels are background; everything else is the file's ids.
  cv::Mat expected = idImage();
  expected.setTo(0, expected == 9);
  EXPECT_EQ(cv::countNonZero(first.ids != expected), 0);
  const Segmentation second = segmenter->segment(kCameraImage, kSecond, 0);
  ASSERT_EQ(second.instances.size(), 2u);
  EXPECT_EQ(second.instances[1].label, "person");
  EXPECT_EQ(second.instances[1].class_id, sensors::kInstanceClassPedestrian);
}

TEST(IdPngSegmenter, TheRightFolderAndTrackedIds) {
  const test::ScratchDir dir("semantics_id_png_stereo");
  fs::create_directories(dir / "left");
  fs::create_directories(dir / "right");
  writePng(dir / "left" / fmt::format("{}.png", kFirst), idImage());
  cv::Mat right = idImage();
  right.setTo(0, right == 3);
  writePng(dir / "right" / fmt::format("{}.png", kFirst), right);
  test::writeFile(dir / "classes.csv", "3,bus\n7,pedestrian\n9,dog\n");
  SegmenterOptions options = idPngOptions(dir / "left", dir / "right");
  options.id_png_classes = (dir / "classes.csv").string();
  options.id_png_tracked_ids = true;
  options.taxonomy.other_movable = "dog";
  EXPECT_TRUE(options.idsNameObjects());
  const auto segmenter = makeSegmenter(options, "unused");
  EXPECT_TRUE(segmenter->idsNameObjects());
  EXPECT_TRUE(options.segmentsRightImage(*segmenter));
  const Segmentation cam1 = segmenter->segment(kCameraImage, kFirst, 1);
  ASSERT_EQ(cam1.instances.size(), 2u);
  EXPECT_EQ(cam1.instances[0].id, 7);
  EXPECT_EQ(cam1.instances[1].id, 9);
  EXPECT_EQ(cam1.instances[1].class_id, sensors::kInstanceClassOtherMovable);
  EXPECT_EQ(cam1.instances[1].area_px, 4);
  // Without a right folder the right image cannot be segmented on request (or by default for
  // tracked ids), unless only the left image is.
  options.id_png_folder_right.clear();
  test::expectError<OptionError>([&] { makeSegmenter(options, "unused"); },
                                 {"semantics.id_png_folder_right", "right_labels: left"});
  options.right_labels = "left";
  EXPECT_FALSE(options.segmentsRightImage(*makeSegmenter(options, "unused")));
  options.right_labels = "segment";
  test::expectError<OptionError>([&] { makeSegmenter(options, "unused"); },
                                 {"semantics.id_png_folder_right", "right_labels segment"});
}

TEST(IdPngSegmenter, BadImagesAreErrorsNamingTheFile) {
  const test::ScratchDir dir("semantics_id_png_bad_images");
  test::writeFile(dir / "classes.csv", "id,label\n3,car\n7,person\n");
  const auto segmenter = makeSegmenter(idPngOptions(dir.path()), "unused");
  const fs::path file = dir / fmt::format("{}.png", kFirst);
  const auto segment = [&] { segmenter->segment(kCameraImage, kFirst, 0); };
  test::expectError(segment, {file.string(), "no instance-id image for this frame", "<t_ns>.png"});
  writePng(file, cv::Mat(30, 40, CV_8UC1, cv::Scalar(3)));
  test::expectError(segment, {file.string(), "8-bit image with 1 channel(s)", "16-bit"});
  writePng(file, cv::Mat(30, 40, CV_16UC3, cv::Scalar(3, 3, 3)));
  test::expectError(segment, {file.string(), "16-bit image with 3 channel(s)"});
  writePng(file, cv::Mat(30, 41, CV_16UC1, cv::Scalar(3)));
  test::expectError(segment, {file.string(), "instance-id image is 41x30, the camera image 40x30"});
  cv::Mat ids = idImage();
  writePng(file, ids);  // id 9 at (30, 25) is not in the table
  test::expectError(segment, {file.string(), "id 9 (pixel (30, 25))", "not in the class table",
                              (dir / "classes.csv").string()});
  ids.setTo(0, ids == 9);
  writePng(file, ids);
  EXPECT_EQ(segmenter->segment(kCameraImage, kFirst, 0).instances.size(), 2u);
}

TEST(IdPngSegmenter, BadTablesAreErrorsNamingFileLineAndField) {
  const test::ScratchDir dir("semantics_id_png_bad_tables");
  const fs::path table = dir / "classes.csv";
  const auto read = [&] { readIdClassTable(table, Taxonomy{}); };
  test::writeFile(table, "id,label\n3,car\n4,spaceship\n");
  test::expectError(read, {"classes.csv:3 [label]", "unknown class 'spaceship'", "COCO"});
  test::writeFile(table, "id,label\n0,car\n");
  test::expectError(read, {"classes.csv:2 [id]", "[1, 65535]"});
  test::writeFile(table, "3,car\n3,bus\n");
  test::expectError(read, {"classes.csv:2 [id]", "listed twice"});
  test::writeFile(table, "12.5,3,car\n");
  test::expectError(read, {"classes.csv:1 [t_ns]"});
  test::writeFile(table, "3\n");
  test::expectError(read, {"classes.csv:1"});
  // A taxonomy label that is no COCO category is accepted.
  Taxonomy riders;
  riders.pedestrian = "person,rider";
  test::writeFile(table, "t_ns,id,label\n5,3,rider\n");
  EXPECT_EQ(readIdClassTable(table, riders).find(5, 3)->class_id,
            sensors::kInstanceClassPedestrian);
  EXPECT_EQ(readIdClassTable(table, riders).find(6, 3), nullptr);
  // A missing folder and a missing option.
  test::expectError([&] { makeSegmenter(idPngOptions(dir / "nowhere"), "unused"); },
                    {(dir / "nowhere").string(), "does not exist"});
  test::expectError<OptionError>([&] { makeSegmenter(idPngOptions(""), "unused"); },
                                 {"semantics.id_png_folder"});
}

}  // namespace
}  // namespace superdyna::semantics

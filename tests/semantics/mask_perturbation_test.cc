// Dilation and erosion of instance masks change each instance as the 3x3 square kernel must.

#include "superdyna/semantics/mask_perturbation.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace superdyna::semantics {
namespace {

int areaOf(const cv::Mat& ids, int id) {
  return cv::countNonZero(ids == id);
}

cv::Rect boundsOf(const cv::Mat& ids, int id) {
  return cv::boundingRect(ids == id);
}

/// A 40x40 image with a 10x10 square of instance 1 at (10, 10).
cv::Mat squareImage() {
  cv::Mat ids(40, 40, CV_16UC1, cv::Scalar(0));
  ids(cv::Rect(10, 10, 10, 10)).setTo(1);
  return ids;
}

TEST(MaskPerturbation, DilationGrowsASquareByOnePixelPerSidePerIteration) {
  for (int iterations = 1; iterations <= 3; ++iterations) {
    cv::Mat ids = squareImage();
    dilateInstances(ids, iterations);
    const int side = 10 + 2 * iterations;
    EXPECT_EQ(areaOf(ids, 1), side * side) << iterations;  // 144, 196, 256: square kernel
    EXPECT_EQ(boundsOf(ids, 1), cv::Rect(10 - iterations, 10 - iterations, side, side));
  }
}

TEST(MaskPerturbation, ErosionShrinksASquareByOnePixelPerSidePerIteration) {
  for (int iterations = 1; iterations <= 3; ++iterations) {
    cv::Mat ids = squareImage();
    erodeInstances(ids, iterations);
    const int side = 10 - 2 * iterations;
    EXPECT_EQ(areaOf(ids, 1), side * side) << iterations;  // 64, 36, 16
  }
  cv::Mat ids = squareImage();
  erodeInstances(ids, 5);  // the paper's 5 iterations remove a 10x10 instance
  EXPECT_EQ(areaOf(ids, 1), 0);
}

TEST(MaskPerturbation, ADiagonalLineThickensAsTheSquareKernelDemands) {
  // The square kernel turns each pixel into its 3x3 block: a 10-pixel diagonal becomes the
  // union of 10 blocks (a cross kernel would give the union of 10 plus-shapes, 32 pixels).
  cv::Mat ids(30, 30, CV_16UC1, cv::Scalar(0));
  for (int i = 0; i < 10; ++i)
    ids.at<std::uint16_t>(10 + i, 10 + i) = 2;
  cv::Mat expected(30, 30, CV_8UC1, cv::Scalar(0));
  for (int i = 0; i < 10; ++i)
    expected(cv::Rect(9 + i, 9 + i, 3, 3)).setTo(255);
  dilateInstances(ids, 1);
  EXPECT_EQ(cv::countNonZero((ids == 2) != expected), 0);
  EXPECT_EQ(areaOf(ids, 2), 9 + 9 * 5);  // the first 3x3 block, then 5 new pixels per step
}

TEST(MaskPerturbation, InstancesGrowOnlyIntoBackgroundAndShrinkAtEachOther) {
  // Two 10x10 squares side by side (columns 10..19 and 20..29).
  cv::Mat ids(40, 50, CV_16UC1, cv::Scalar(0));
  ids(cv::Rect(10, 10, 10, 10)).setTo(1);
  ids(cv::Rect(20, 10, 10, 10)).setTo(2);
  cv::Mat dilated = ids.clone();
  dilateInstances(dilated, 1);
  // Each gains its three free sides only, 12 rows x 11 columns, except the two background pixels
  // diagonal to both (column 20 of rows 9 and 20): both grow into them, the lower id gets them.
  EXPECT_EQ(areaOf(dilated, 1), 12 * 11 + 2);
  EXPECT_EQ(areaOf(dilated, 2), 12 * 11 - 2);
  EXPECT_EQ(dilated.at<std::uint16_t>(9, 20), 1);
  EXPECT_EQ(dilated.at<std::uint16_t>(20, 20), 1);
  cv::Mat eroded = ids.clone();
  erodeInstances(eroded, 1);
  // Erosion treats the other instance as outside: each loses its border on all four sides.
  EXPECT_EQ(areaOf(eroded, 1), 8 * 8);
  EXPECT_EQ(areaOf(eroded, 2), 8 * 8);
}

TEST(MaskPerturbation, PerturbMasksUpdatesBoxesAndDropsErodedInstances) {
  Segmentation segmentation;
  segmentation.ids = squareImage();
  segmentation.ids(cv::Rect(30, 30, 2, 2)).setTo(7);
  Instance car, person;
  car.id = 1;
  car.class_id = sensors::kInstanceClassVehicle;
  person.id = 7;
  person.class_id = sensors::kInstanceClassPedestrian;
  segmentation.instances = {car, person};
  updateBoxesAndAreas(segmentation);
  const cv::Mat original = segmentation.ids.clone();
  perturbMasks(segmentation, 1, 2);  // 10 -> 12 -> 8 wide; the 2x2 one: 4 -> 0
  ASSERT_EQ(segmentation.instances.size(), 1u);
  EXPECT_EQ(segmentation.instances[0].id, 1);
  EXPECT_EQ(segmentation.instances[0].area_px, 64);
  EXPECT_EQ(segmentation.instances[0].box, cv::Rect(11, 11, 8, 8));
  EXPECT_EQ(cv::countNonZero(original != squareImage()), 4);  // the input image is untouched
}

}  // namespace
}  // namespace superdyna::semantics

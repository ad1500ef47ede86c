// Overlays with the moving-object test on: every decided object drawn in the style of its
// decision (moving filled, static outlined, unverified dashed), labelled, with a legend.

#include "superdyna/system/frame_overlays.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <vector>

namespace superdyna::system {
namespace {

const cv::Vec3b kGrey(128, 128, 128);
const cv::Vec3b kGreen(0, 200, 0);
const cv::Vec3b kRed(0, 0, 255);
const cv::Vec3b kYellow(0, 220, 255);

/// A 320x240 grey frame with three objects: a static vehicle (1), a moving pedestrian (2) and an
/// unverified vehicle (3) whose keypoints were dropped; a keypoint on each, one on the background.
struct Scene {
  sensors::FrameBundle bundle;
  tracking::Frame frame;
  tracking::TrackingResult result;

  Scene() {
    bundle.t_ns = 1000;
    bundle.image0 = cv::Mat(240, 320, CV_8UC1, cv::Scalar(128));
    sensors::InstanceMasks masks;
    masks.cam0 = cv::Mat::zeros(240, 320, CV_16UC1);
    masks.cam0(cv::Rect(200, 40, 41, 41)).setTo(1);
    masks.cam0(cv::Rect(60, 150, 41, 41)).setTo(2);
    masks.cam0(cv::Rect(220, 150, 61, 51)).setTo(3);
    masks.class_of_instance = {{1, sensors::kInstanceClassVehicle},
                               {2, sensors::kInstanceClassPedestrian},
                               {3, sensors::kInstanceClassVehicle}};
    bundle.masks = masks;
    const std::vector<Eigen::Vector2d> pixels = {{220, 60}, {80, 170}, {250, 175}, {150, 120}};
    for (const Eigen::Vector2d& pixel : pixels) {
      features::Keypoint k;
      k.pixel = pixel;
      frame.features.keypoints.push_back(k);
    }
    result.t_ns = bundle.t_ns;
    dynamic::ObjectDecision still{1, sensors::kInstanceClassVehicle};
    still.pairs = 6;
    still.tested = 6;
    still.decision = dynamic::ObjectState::kStatic;
    dynamic::ObjectDecision walking{2, sensors::kInstanceClassPedestrian};
    walking.pairs = 5;
    walking.tested = 5;
    walking.decision = dynamic::ObjectState::kMoving;
    walking.dropped = true;
    dynamic::ObjectDecision unknown{3, sensors::kInstanceClassVehicle};
    unknown.decision = dynamic::ObjectState::kUnverified;
    unknown.dropped = true;
    result.moving.objects = {still, walking, unknown};
    result.moving.drop = {0, 1, 1, 0};
  }
};

cv::Mat drawn(const Scene& scene) {
  FrameOverlays overlays(1, true);
  overlays.remember(scene.bundle, scene.frame);
  const std::optional<FrameOverlay> overlay = overlays.draw(scene.result);
  EXPECT_TRUE(overlay.has_value());
  return overlay ? overlay->image : cv::Mat();
}

/// Pixels of `colour` on the border of `rect` (the outline of a mask drawn on it).
int onBorder(const cv::Mat& image, const cv::Rect& rect, const cv::Vec3b& colour) {
  int count = 0;
  for (int x = rect.x; x < rect.x + rect.width; ++x)
    for (int y : {rect.y, rect.y + rect.height - 1})
      count += image.at<cv::Vec3b>(y, x) == colour ? 1 : 0;
  for (int y = rect.y; y < rect.y + rect.height; ++y)
    for (int x : {rect.x, rect.x + rect.width - 1})
      count += image.at<cv::Vec3b>(y, x) == colour ? 1 : 0;
  return count;
}

TEST(FrameOverlays, EveryDecidedObjectIsDrawnInItsDecisionsStyle) {
  const cv::Mat image = drawn(Scene());
  ASSERT_EQ(image.type(), CV_8UC3);
  // Static: a solid green outline, the mask not filled.
  const cv::Rect still(200, 40, 41, 41);
  EXPECT_GT(onBorder(image, still, kGreen), 140);  // of 164: the label may touch the top
  EXPECT_EQ(image.at<cv::Vec3b>(50, 235), kGrey);
  // Moving: a red outline and the mask filled.
  const cv::Rect walking(60, 150, 41, 41);
  EXPECT_GT(onBorder(image, walking, kRed), 140);
  EXPECT_NE(image.at<cv::Vec3b>(185, 95), kGrey);
  // Unverified: a dashed yellow outline (about half of its border), the mask not filled.
  const cv::Rect unknown(220, 150, 61, 51);
  const int dashes = onBorder(image, unknown, kYellow);
  EXPECT_GT(dashes, 60);
  EXPECT_LT(dashes, 200);
  EXPECT_EQ(image.at<cv::Vec3b>(195, 275), kGrey);
  // Keypoints: kept green, dropped red.
  EXPECT_EQ(image.at<cv::Vec3b>(120, 150), kGreen);
  EXPECT_EQ(image.at<cv::Vec3b>(175, 250), kRed);
  // The legend's box in the top-left corner, with its three styles' swatches.
  EXPECT_EQ(image.at<cv::Vec3b>(2, 2), cv::Vec3b(40, 40, 40));
  EXPECT_EQ(image.at<cv::Vec3b>(6, 15), kRed);                     // moving: red outline ...
  EXPECT_EQ(image.at<cv::Vec3b>(11, 15), cv::Vec3b(255, 120, 0));  // ... around a filled mask
  EXPECT_EQ(image.at<cv::Vec3b>(22, 6), kGreen);                   // static: green outline
  EXPECT_EQ(image.at<cv::Vec3b>(27, 15), cv::Vec3b(40, 40, 40));   // ... not filled
}

TEST(FrameOverlays, LabelsNameTheDecisionAndWhyAnUnverifiedObjectWasDropped) {
  const Scene scene;
  const dynamic::MovingObjectOptions options;  // min_pairs 1, drop_unverified
  EXPECT_EQ(describeObject(scene.result.moving.objects[0], options), "static vehicle 1");
  EXPECT_EQ(describeObject(scene.result.moving.objects[1], options), "moving pedestrian 2");
  EXPECT_EQ(describeObject(scene.result.moving.objects[2], options),
            "unverified vehicle 3: 0 of 1 pairs to the previous frame, dropped "
            "(dynamic.drop_unverified)");
  dynamic::ObjectDecision kept = scene.result.moving.objects[2];
  kept.pairs = 4;
  kept.dropped = false;
  EXPECT_EQ(describeObject(kept, options),
            "unverified vehicle 3: none of its 4 pairs testable, kept");
}

/// Rows of `image` within `columns` holding a pixel of a green label's text (anti-aliased: mostly
/// green), from `top` to `bottom`.
int greenTextRows(const cv::Mat& image, cv::Range columns, int top, int bottom) {
  int rows = 0;
  for (int y = top; y < bottom; ++y) {
    bool green = false;
    for (int x = columns.start; x < columns.end && !green; ++x) {
      const cv::Vec3b p = image.at<cv::Vec3b>(y, x);
      green = p[1] > 150 && p[0] < 80 && p[2] < 80;
    }
    rows += green ? 1 : 0;
  }
  return rows;
}

TEST(FrameOverlays, LabelsOfNeighbouringObjectsDoNotCoverEachOther) {
  // Two static vehicles side by side at the same height: the second label, at the first one's
  // line, would run into it ("static vehicle 11" is about 100 px wide); it goes a line higher.
  Scene scene;
  scene.bundle.masks->cam0.setTo(0);
  scene.bundle.masks->cam0(cv::Rect(20, 120, 41, 41)).setTo(11);
  scene.bundle.masks->cam0(cv::Rect(80, 120, 41, 41)).setTo(12);
  scene.bundle.masks->class_of_instance = {{11, sensors::kInstanceClassVehicle},
                                           {12, sensors::kInstanceClassVehicle}};
  dynamic::ObjectDecision left{11, sensors::kInstanceClassVehicle};
  left.decision = dynamic::ObjectState::kStatic;
  dynamic::ObjectDecision right = left;
  right.instance_id = 12;
  scene.result.moving.objects = {left, right};
  const cv::Mat image = drawn(scene);
  ASSERT_FALSE(image.empty());
  // The first label stands on the line just above the boxes (its baseline at y = 116), the second
  // one a line (about 16 px) higher, clear of it.
  EXPECT_GE(greenTextRows(image, cv::Range(20, 200), 104, 118), 5);
  EXPECT_GE(greenTextRows(image, cv::Range(80, 200), 88, 102), 5);
}

}  // namespace
}  // namespace superdyna::system

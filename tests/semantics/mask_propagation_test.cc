// Mask propagation moves each instance with its own keypoints' image motion, falls back to the
// common motion for instances without matches, and shifts id images exactly.

#include "superdyna/semantics/mask_propagation.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "superdyna/core/error.h"
#include "superdyna/features/orb_extractor.h"

namespace superdyna::semantics {
namespace {

int areaOf(const cv::Mat& ids, int id) {
  return cv::countNonZero(ids == id);
}

TEST(ShiftInstances, MovesEachInstanceByItsOwnShiftAndClipsAtTheBorder) {
  cv::Mat ids(40, 60, CV_16UC1, cv::Scalar(0));
  ids(cv::Rect(10, 10, 8, 6)).setTo(1);
  ids(cv::Rect(50, 30, 6, 6)).setTo(2);
  ids(cv::Rect(30, 5, 4, 4)).setTo(3);
  const cv::Mat out = shiftInstances(ids, {{1, {5, -3}}, {2, {7, 0}}});
  EXPECT_EQ(cv::boundingRect(out == 1), cv::Rect(15, 7, 8, 6));
  EXPECT_EQ(areaOf(out, 1), 48);
  // Instance 2 leaves the image by 3 of its 6 columns.
  EXPECT_EQ(cv::boundingRect(out == 2), cv::Rect(57, 30, 3, 6));
  EXPECT_EQ(areaOf(out, 2), 18);
  EXPECT_EQ(cv::boundingRect(out == 3), cv::Rect(30, 5, 4, 4));  // no entry: stays
  EXPECT_EQ(areaOf(out, 0), 40 * 60 - 48 - 18 - 16);
}

TEST(ShiftInstances, TheLargerIdWinsWhereShiftedInstancesOverlap) {
  cv::Mat ids(20, 20, CV_16UC1, cv::Scalar(0));
  ids(cv::Rect(2, 2, 4, 4)).setTo(5);
  ids(cv::Rect(10, 2, 4, 4)).setTo(4);
  const cv::Mat out = shiftInstances(ids, {{5, {6, 0}}, {4, {-2, 0}}});
  // 5 covers x 8..11, 4 covers x 8..11: the same pixels.
  EXPECT_EQ(areaOf(out, 5), 16);
  EXPECT_EQ(areaOf(out, 4), 0);
}

/// A textured image: random grey blocks (corners everywhere).
cv::Mat texture(int rows, int cols, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> grey(0, 255);
  cv::Mat image(rows, cols, CV_8UC1);
  for (int r = 0; r < rows; r += 6) {
    for (int c = 0; c < cols; c += 6)
      image(cv::Rect(c, r, std::min(6, cols - c), std::min(6, rows - r))).setTo(grey(rng));
  }
  return image;
}

/// A scene of a textured background with a textured object pasted at `object_at`, the whole
/// view moved by `view_shift` (the background's image motion).
cv::Mat sceneImage(const cv::Mat& background, const cv::Mat& object, cv::Point view_shift,
                   cv::Point object_at) {
  const cv::Rect view(40 - view_shift.x, 40 - view_shift.y, 320, 240);
  cv::Mat image = background(view).clone();
  object.copyTo(image(cv::Rect(object_at, object.size())));
  return image;
}

struct Scene {
  cv::Mat background = texture(320, 480, 1);
  cv::Mat object = texture(60, 80, 2);
  features::OrbExtractor orb;
  Scene() : orb(orbOptions()) {}
  static features::OrbOptions orbOptions() {
    features::OrbOptions options;
    options.features = 1000;
    return options;
  }
  /// The true id image of a frame with the object (instance 7) at `object_at`.
  cv::Mat ids(cv::Point object_at) const {
    cv::Mat ids(240, 320, CV_16UC1, cv::Scalar(0));
    ids(cv::Rect(object_at, object.size())).setTo(7);
    return ids;
  }
};

sensors::InstanceMasks masksOf(const cv::Mat& ids) {
  sensors::InstanceMasks masks;
  masks.cam0 = ids;
  masks.class_of_instance = {{7, sensors::kInstanceClassVehicle}};
  return masks;
}

TEST(MaskPropagator, AnObjectMovingAgainstTheBackgroundTakesItsMaskAlong) {
  Scene scene;
  const cv::Point object0(100, 80), object1(118, 86);  // the object moves by (18, 6) in view
  const cv::Point view1(-4, 2);                        // while the background moves by (-4, 2)
  const features::FeatureSet first =
      scene.orb.extract(sceneImage(scene.background, scene.object, {0, 0}, object0));
  const features::FeatureSet second =
      scene.orb.extract(sceneImage(scene.background, scene.object, view1, object1));

  MaskPropagator propagator;
  EXPECT_FALSE(propagator.hasReference());
  propagator.setReference(masksOf(scene.ids(object0)), first);
  PropagationStats stats;
  const sensors::InstanceMasks moved = propagator.propagate(second, &stats);

  EXPECT_GT(stats.matches, 200);
  // The background is most of the view (keypoints of coarse octaves sit off the pixel grid).
  EXPECT_LT((stats.median_motion - Eigen::Vector2d(-4, 2)).norm(), 1.0);
  EXPECT_EQ(stats.instances_own_motion, 1);
  EXPECT_EQ(cv::boundingRect(moved.cam0 == 7), cv::Rect(object1, scene.object.size()));
  EXPECT_EQ(moved.class_of_instance, masksOf(scene.ids(object0)).class_of_instance);
  EXPECT_TRUE(moved.cam1.empty());
}

TEST(MaskPropagator, AnInstanceWithoutMatchesMovesWithTheCommonMotion) {
  Scene scene;
  const cv::Point object0(100, 80);
  const features::FeatureSet first =
      scene.orb.extract(sceneImage(scene.background, scene.object, {0, 0}, object0));
  // The object is gone from the second image: its mask follows the background.
  const cv::Rect view(40 - 5, 40 - 3, 320, 240);
  const features::FeatureSet second = scene.orb.extract(scene.background(view).clone());

  MaskPropagator propagator;
  propagator.setReference(masksOf(scene.ids(object0)), first);
  PropagationStats stats;
  const sensors::InstanceMasks moved = propagator.propagate(second, &stats);
  EXPECT_EQ(stats.instances_common_motion, 1);
  EXPECT_EQ(cv::boundingRect(moved.cam0 == 7),
            cv::Rect(object0 + cv::Point(5, 3), scene.object.size()));
}

TEST(MaskPropagator, SearchesWhereTheLastMotionPutsTheKeypoints) {
  Scene scene;
  PropagationOptions options;
  options.radius_px = 12.0;
  MaskPropagator propagator(options);
  // The view accelerates to the left: 20 px, then 40 px. The first step finds its motion with the
  // doubled radius; the second only from where the first motion puts the keypoints (40 - 20 is
  // within 24 px, 40 is not).
  cv::Point object(150, 80);
  int view = 0;
  features::FeatureSet previous =
      scene.orb.extract(sceneImage(scene.background, scene.object, {view, 0}, object));
  propagator.setReference(masksOf(scene.ids(object)), previous);
  for (const int motion : {20, 40}) {
    object.x -= motion;
    view -= motion;
    const features::FeatureSet next =
        scene.orb.extract(sceneImage(scene.background, scene.object, {view, 0}, object));
    PropagationStats stats;
    const sensors::InstanceMasks moved = propagator.propagate(next, &stats);
    EXPECT_GT(stats.matches, 200) << motion;
    EXPECT_LT((stats.median_motion - Eigen::Vector2d(-motion, 0)).norm(), 1.0) << motion;
    EXPECT_EQ(cv::boundingRect(moved.cam0 == 7), cv::Rect(object, scene.object.size())) << motion;
    propagator.setReference(moved, next);
  }
}

TEST(PropagationOptions, NamesTheInvalidField) {
  PropagationOptions options;
  options.radius_px = 0.0;
  try {
    options.validate();
    FAIL() << "no error";
  } catch (const OptionError& e) {
    EXPECT_NE(std::string(e.what()).find("semantics.propagation_radius_px"), std::string::npos);
  }
  options = {};
  options.ratio = 1.5;
  EXPECT_THROW(options.validate(), OptionError);
}

}  // namespace
}  // namespace superdyna::semantics

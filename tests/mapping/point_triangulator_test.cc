#include "superdyna/mapping/point_triangulator.h"

#include <gtest/gtest.h>

#include <iostream>
#include <limits>
#include <opencv2/core.hpp>
#include <random>

#include "superdyna/core/error.h"
#include "superdyna/features/feature_set.h"
#include "support/test_support.h"

namespace superdyna::mapping {
namespace {

constexpr double kFocalPx = 450.0;

/// Two keyframes with known poses looking at a scene of random points, each point seen by one
/// keypoint per keyframe with the same random descriptor. The first `shared` points are already
/// map points (they make the keyframes covisible); the others are for the triangulator.
class TwoKeyFrameScene : public ::testing::Test {
 protected:
  static constexpr int kShared = 30;
  static constexpr int kFree = 200;

  void SetUp() override {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> xy(-0.5, 0.5), depth(3.0, 8.0);
    std::uniform_int_distribution<int> byte(0, 255);
    const int n = kShared + kFree;
    for (int i = 0; i < n; ++i) {
      const double z = depth(rng);
      points.emplace_back(xy(rng) * z, xy(rng) * z, z);
    }
    cv::Mat descriptors = floatDescriptors() ? cv::Mat(n, 64, CV_32FC1) : cv::Mat(n, 32, CV_8UC1);
    std::normal_distribution<float> component(0.0f, 1.0f);
    for (int r = 0; r < n; ++r) {
      if (floatDescriptors()) {
        for (int c = 0; c < 64; ++c)
          descriptors.at<float>(r, c) = component(rng);
        cv::normalize(descriptors.row(r), descriptors.row(r));  // unit norm, as XFeat's
      } else {
        for (int c = 0; c < 32; ++c)
          descriptors.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(byte(rng));
      }
    }
    // The body is the camera here; keyframe 1 moved 0.4 m sideways and turned slightly.
    poses = {SE3d(), SE3d(expSO3(Eigen::Vector3d(0.0, -0.05, 0.0)), Eigen::Vector3d(0.4, 0, 0.05))};
    // Keyframe 1 lists its keypoints in reverse order, so indices differ between the two.
    for (int k = 0; k < 2; ++k) {
      map::KeyFrame kf;
      kf.T_w_b = poses[k];
      kf.descriptors = cv::Mat(n, descriptors.cols, descriptors.type());
      for (int j = 0; j < n; ++j) {
        const int i = k == 0 ? j : n - 1 - j;
        const Eigen::Vector3d p_c = poses[k].inverse() * points[static_cast<std::size_t>(i)];
        map::KeyFrameKeypoint keypoint;
        keypoint.class_id = classOf(k, i);
        keypoint.normalized = p_c.head<2>() / p_c.z();
        keypoint.pixel = kFocalPx * keypoint.normalized + Eigen::Vector2d(376, 240);
        kf.keypoints.push_back(keypoint);
        descriptors.row(i).copyTo(kf.descriptors.row(j));
        if (floatDescriptors() && k == 1) {
          // The second view sees each point a little differently (distance about 0.16).
          for (int c = 0; c < kf.descriptors.cols; ++c)
            kf.descriptors.at<float>(j, c) += 0.02f * component(rng);
          cv::normalize(kf.descriptors.row(j), kf.descriptors.row(j));
        }
      }
      editKeyFrame(k, kf);
      ids[k] = map.addKeyFrame(std::move(kf));
    }
    for (int i = 0; i < kShared; ++i) {
      map::MapPoint point;
      point.p_w = points[static_cast<std::size_t>(i)];
      point.descriptor = descriptors.row(i).clone();
      const map::MapPointId id = map.addMapPoint(std::move(point));
      map.addObservation(id, ids[0], i);
      map.addObservation(id, ids[1], n - 1 - i);
    }
  }

  /// Float descriptors (learned extractors, Euclidean distance) instead of binary ones.
  virtual bool floatDescriptors() const { return false; }
  /// Changes keyframe k (0 or 1) before it enters the map.
  virtual void editKeyFrame(int /*k*/, map::KeyFrame& /*kf*/) const {}
  /// The class_id of point i's keypoint in keyframe k.
  virtual int classOf(int /*keyframe*/, int /*point*/) const { return features::kClassBackground; }

  optim::ReprojectionCamera camera() const {
    optim::ReprojectionCamera c;
    c.fx = c.fy = kFocalPx;
    return c;
  }

  map::Map map;
  std::vector<Eigen::Vector3d> points;
  std::vector<SE3d> poses;
  map::KeyFrameId ids[2] = {map::kNoKeyFrame, map::kNoKeyFrame};
};

TEST_F(TwoKeyFrameScene, TriangulatesTheFreeKeypointsAtTheirTruePositions) {
  const PointTriangulator triangulator({}, camera());
  const std::vector<map::MapPointId> created = triangulator.createPoints(map, ids[1]);
  // Points whose rays are nearly parallel (far and central) are rightly skipped; most are not.
  EXPECT_GT(static_cast<int>(created.size()), 170);
  EXPECT_LE(static_cast<int>(created.size()), kFree);
  const int n = kShared + kFree;
  for (const map::MapPointId id : created) {
    const auto point = map.mapPoint(id);
    ASSERT_TRUE(point);
    ASSERT_EQ(point->numObservations(), 2);
    const int index0 = point->observations.at(ids[0]);
    EXPECT_EQ(point->observations.at(ids[1]), n - 1 - index0);  // the right pair
    EXPECT_GE(index0, kShared);
    EXPECT_LT((point->p_w - points[static_cast<std::size_t>(index0)]).norm(), 1e-6);
    EXPECT_GT(point->max_distance_m, 0.0);
  }
  EXPECT_EQ(map.consistencyError(), "");
  // Everything that could be triangulated was: a second pass adds nothing.
  EXPECT_TRUE(triangulator.createPoints(map, ids[1]).empty());
}

/// The scene with keypoints whose undistortion failed (normalised coordinates NaN, as the tracker
/// stores them): free point kShared's keypoint in keyframe 0, and in keyframe 0 a second keypoint
/// with free point kShared + 1's descriptor (a look-alike far out in the image).
/// Keyframe 0's free keypoints at even indices carry a stereo depth.
class StereoKeyFrameScene : public TwoKeyFrameScene {
 protected:
  void editKeyFrame(int k, map::KeyFrame& kf) const override {
    if (k != 0) return;
    for (std::size_t i = kShared; i < kf.keypoints.size(); i += 2)
      kf.keypoints[i].depth_m = 5.0;
  }
};

TEST_F(StereoKeyFrameScene, StereoRigsTriangulateOnlyKeypointsWithoutStereoDepth) {
  // Without the option more than 170 of the 200 free keypoints become points (test above); half
  // of them have a stereo depth in keyframe 0 here.
  PointTriangulatorOptions options;
  options.skip_stereo_keypoints = true;
  const std::vector<map::MapPointId> created =
      PointTriangulator(options, camera()).createPoints(map, ids[1]);
  EXPECT_GT(created.size(), 70u);
  EXPECT_LE(created.size(), static_cast<std::size_t>(kFree / 2));
  for (const map::MapPointId id : created) {
    const int index = map.mapPoint(id)->observations.at(ids[0]);
    EXPECT_FALSE(map.keyFrame(ids[0])->keypoints[static_cast<std::size_t>(index)].hasStereo());
  }
}

class FailedUndistortionScene : public TwoKeyFrameScene {
 protected:
  static constexpr int kFailed = kShared;
  static constexpr int kLookAlike = kShared + 1;
  static constexpr int kLookAlikeIndex = kShared + kFree;  // appended to keyframe 0

  void editKeyFrame(int k, map::KeyFrame& kf) const override {
    if (k != 0) return;
    const Eigen::Vector2d nan = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
    kf.keypoints[kFailed].normalized = nan;
    map::KeyFrameKeypoint look_alike = kf.keypoints[kLookAlike];
    look_alike.pixel = Eigen::Vector2d(2.0, 3.0);
    look_alike.normalized = nan;
    kf.keypoints.push_back(look_alike);
    cv::vconcat(kf.descriptors, kf.descriptors.row(kLookAlike).clone(), kf.descriptors);
  }
};

TEST_F(FailedUndistortionScene, KeypointsWhoseUndistortionFailedAreNeverTriangulated) {
  const PointTriangulator triangulator({}, camera());
  // Keyframe 1 searches keyframe 0, where the invalid keypoints are.
  const std::vector<map::MapPointId> created = triangulator.createPoints(map, ids[1]);
  EXPECT_GT(static_cast<int>(created.size()), 170);
  const map::KeyFrame kf0 = *map.keyFrame(ids[0]);
  // No ray, no point: the failed keypoint observes nothing...
  EXPECT_EQ(kf0.map_points[kFailed], map::kNoMapPoint);
  EXPECT_EQ(kf0.map_points[kLookAlikeIndex], map::kNoMapPoint);
  // ... and the invalid look-alike does not make the true match ambiguous (ratio test).
  const map::MapPointId id = kf0.map_points[kLookAlike];
  ASSERT_NE(id, map::kNoMapPoint);
  EXPECT_LT((map.mapPoint(id)->p_w - points[static_cast<std::size_t>(kLookAlike)]).norm(), 1e-6);
  EXPECT_EQ(map.consistencyError(), "");
}

class TwoKeyFrameFloatScene : public TwoKeyFrameScene {
 protected:
  bool floatDescriptors() const override { return true; }
};

TEST_F(TwoKeyFrameFloatScene, MatchesFloatDescriptorsByEuclideanDistance) {
  PointTriangulatorOptions options;
  options.max_distance = 0;  // the Hamming bound does not apply to float descriptors
  const PointTriangulator triangulator(options, camera());
  const std::vector<map::MapPointId> created = triangulator.createPoints(map, ids[1]);
  EXPECT_GT(static_cast<int>(created.size()), 170);
  const int n = kShared + kFree;
  for (const map::MapPointId id : created) {
    const auto point = map.mapPoint(id);
    ASSERT_TRUE(point);
    const int index0 = point->observations.at(ids[0]);
    EXPECT_EQ(point->observations.at(ids[1]), n - 1 - index0);
    EXPECT_LT((point->p_w - points[static_cast<std::size_t>(index0)]).norm(), 1e-6);
  }
}

TEST_F(TwoKeyFrameFloatScene, TheEuclideanBoundRejectsDistantDescriptors) {
  PointTriangulatorOptions options;
  options.max_l2_distance = 0.05;  // below the views' descriptor differences
  EXPECT_EQ(PointTriangulator(options, camera()).createPoints(map, ids[1]).size(), 0u);
}

/// Every third free point is a vehicle in both keyframes; every other free point is a vehicle in
/// keyframe 0 but background in keyframe 1 (a mislabelled or occluding edge): its descriptor twin
/// lies in another class.
class TwoKeyFrameLabelledScene : public TwoKeyFrameScene {
 protected:
  int classOf(int keyframe, int point) const override {
    if (point < kShared) return features::kClassBackground;
    if (point % 3 == 0) return features::kClassVehicle;
    if (crossesClasses(point) && keyframe == 0) return features::kClassVehicle;
    return features::kClassBackground;
  }
  static bool crossesClasses(int point) {
    return point >= kShared && point % 3 != 0 && point % 2 == 0;
  }
  /// Free points whose two keypoints carry different classes.
  static std::size_t crossClassFree() {
    std::size_t count = 0;
    for (int i = kShared; i < kShared + kFree; ++i)
      if (crossesClasses(i)) ++count;
    return count;
  }
};

TEST_F(TwoKeyFrameLabelledScene, ClassWiseMatchingRefusesCrossClassPairs) {
  PointTriangulatorOptions options;
  options.same_class_only = false;
  const std::size_t blind = PointTriangulator(options, camera()).createPoints(map, ids[1]).size();
  const std::size_t blind_cross = map.numCrossClassMapPoints();
  std::cout << "triangulation, class-blind: " << blind << " points, " << blind_cross
            << " cross-class\n";
  EXPECT_EQ(blind, static_cast<std::size_t>(kFree));  // every pair has parallax enough here
  EXPECT_EQ(blind_cross, crossClassFree());
}

TEST_F(TwoKeyFrameLabelledScene, ClassWiseMatchingTriangulatesOnlyWithinAClass) {
  PointTriangulatorOptions options;
  options.same_class_only = true;
  const std::vector<map::MapPointId> created =
      PointTriangulator(options, camera()).createPoints(map, ids[1]);
  std::cout << "triangulation, class-wise: " << created.size() << " points, "
            << map.numCrossClassMapPoints() << " cross-class\n";
  EXPECT_EQ(map.numCrossClassMapPoints(), 0u);
  int vehicles = 0;
  for (const map::MapPointId id : created) {
    const auto point = map.mapPoint(id);
    ASSERT_TRUE(point);
    const int index0 = point->observations.at(ids[0]);
    EXPECT_FALSE(crossesClasses(index0)) << "point " << index0 << " crosses classes";
    if (point->class_id == features::kClassVehicle) ++vehicles;
  }
  // Every other free point is still triangulated, the same-class vehicles among them.
  EXPECT_EQ(created.size(), kFree - crossClassFree());
  EXPECT_GT(vehicles, 60);
}

TEST_F(TwoKeyFrameScene, SkipsNeighboursWithoutBaseline) {
  map.setKeyFramePose(ids[1], SE3d(poses[1].q, Eigen::Vector3d(0.001, 0, 0)));
  const PointTriangulator triangulator({}, camera());
  EXPECT_TRUE(triangulator.createPoints(map, ids[1]).empty());
}

TEST_F(TwoKeyFrameScene, WrongPosesGiveNoPoints) {
  // With keyframe 1 moved up instead of sideways, the epipolar lines miss the true matches.
  map.setKeyFramePose(ids[1], SE3d(poses[1].q, Eigen::Vector3d(0.0, 0.4, 0.05)));
  const PointTriangulator triangulator({}, camera());
  EXPECT_LT(triangulator.createPoints(map, ids[1]).size(), 10u);
}

TEST(PointTriangulatorOptions, RejectsBadValues) {
  PointTriangulatorOptions options;
  options.neighbours = 0;
  test::expectError<OptionError>([&] { options.validate(); }, {"triangulation_neighbours"});
  options = {};
  options.ratio = 0.0;
  test::expectError<OptionError>([&] { options.validate(); }, {"triangulation_ratio"});
  options = {};
  options.max_l2_distance = -1.0;
  test::expectError<OptionError>([&] { options.validate(); }, {"triangulation_max_l2_distance"});
}

}  // namespace
}  // namespace superdyna::mapping

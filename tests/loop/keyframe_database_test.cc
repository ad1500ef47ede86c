#include "superdyna/loop/keyframe_database.h"

#include <gtest/gtest.h>

#include <random>

#include "superdyna/features/feature_set.h"

namespace superdyna::loop {
namespace {

/// `rows` random 32-byte descriptors.
cv::Mat randomBinary(int rows, std::mt19937& rng) {
  cv::Mat out(rows, 32, CV_8UC1);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < 32; ++c)
      out.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(rng() & 0xff);
  return out;
}

/// The same place seen again: every descriptor with `bits` random bits flipped.
cv::Mat withFlippedBits(const cv::Mat& rows, int bits, std::mt19937& rng) {
  cv::Mat out = rows.clone();
  for (int r = 0; r < out.rows; ++r) {
    for (int b = 0; b < bits; ++b) {
      const int bit = static_cast<int>(rng() % 256);
      out.at<std::uint8_t>(r, bit / 8) ^= static_cast<std::uint8_t>(1u << (bit % 8));
    }
  }
  return out;
}

cv::Mat randomFloat(int rows, std::mt19937& rng) {
  std::normal_distribution<float> normal;
  cv::Mat out(rows, 64, CV_32FC1);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < 64; ++c)
      out.at<float>(r, c) = normal(rng);
  return out;
}

TEST(KeyFrameDatabase, RetrievesTheRevisitedKeyFrameAmongDistractors) {
  std::mt19937 rng(3);
  KeyFrameDatabase database;
  std::vector<cv::Mat> places;
  for (int k = 0; k < 40; ++k) {
    places.push_back(randomBinary(200, rng));
    database.add(k, places.back());
  }
  EXPECT_EQ(database.numKeyFrames(), 40u);
  EXPECT_EQ(database.numDescriptors(), 8000u);
  EXPECT_EQ(database.descriptorBytes(), 8000u * 32u);
  // Place 17 seen again: 120 of its descriptors with 20 of 256 bits changed, 80 new ones.
  cv::Mat query = withFlippedBits(places[17].rowRange(0, 120), 20, rng);
  cv::vconcat(query, randomBinary(80, rng), query);
  const std::vector<PlaceScore> scores = database.query(query);
  ASSERT_FALSE(scores.empty());
  EXPECT_EQ(scores.front().id, 17);
  EXPECT_NEAR(scores.front().score, 120.0 / 200.0, 0.05);
  // Unrelated descriptors lie ~128 bits from everything: beyond max_hamming, no vote.
  for (std::size_t i = 1; i < scores.size(); ++i)
    EXPECT_LT(scores[i].votes, 5);
}

TEST(KeyFrameDatabase, RetrievesFloatDescriptorsByCosine) {
  std::mt19937 rng(5);
  KeyFrameDatabase database;
  std::vector<cv::Mat> places;
  for (int k = 0; k < 30; ++k) {
    places.push_back(randomFloat(150, rng));
    database.add(100 + k, places.back());
  }
  // Place 108 again, scaled (cosine ignores it) and slightly perturbed.
  cv::Mat query = places[8].rowRange(0, 100) * 3.0;
  query += randomFloat(100, rng) * 0.3;
  const std::vector<PlaceScore> scores = database.query(query);
  ASSERT_FALSE(scores.empty());
  EXPECT_EQ(scores.front().id, 108);
  EXPECT_GT(scores.front().score, 0.9);
  ASSERT_GT(scores.size(), 0u);
  for (std::size_t i = 1; i < scores.size(); ++i)
    EXPECT_LT(scores[i].votes, 5);
}

TEST(KeyFrameDatabase, RejectsAnotherDescriptorType) {
  std::mt19937 rng(1);
  KeyFrameDatabase database;
  database.add(0, randomBinary(10, rng));
  EXPECT_THROW(database.add(1, randomFloat(10, rng)), std::invalid_argument);
  EXPECT_THROW(database.query(randomFloat(10, rng)), std::invalid_argument);
}

TEST(PlaceDescriptorRows, KeepsBackgroundKeypointsObservingPointsFirst) {
  std::mt19937 rng(2);
  map::KeyFrame keyframe;
  keyframe.descriptors = randomBinary(6, rng);
  keyframe.keypoints.resize(6);
  keyframe.map_points.assign(6, map::kNoMapPoint);
  keyframe.keypoints[1].class_id = features::kClassVehicle;  // movable: never votes
  keyframe.keypoints[4].class_id = features::kClassPedestrian;
  keyframe.map_points[3] = 42;
  keyframe.map_points[4] = 43;
  const cv::Mat rows = placeDescriptorRows(keyframe, 3);
  ASSERT_EQ(rows.rows, 3);
  // Keypoint 3 (observes a point), then 0 and 2; 5 is over the limit.
  EXPECT_EQ(cv::norm(rows.row(0), keyframe.descriptors.row(3), cv::NORM_HAMMING), 0.0);
  EXPECT_EQ(cv::norm(rows.row(1), keyframe.descriptors.row(0), cv::NORM_HAMMING), 0.0);
  EXPECT_EQ(cv::norm(rows.row(2), keyframe.descriptors.row(2), cv::NORM_HAMMING), 0.0);
  EXPECT_EQ(placeDescriptorRows(keyframe, 100).rows, 4);
}

TEST(PlaceDescriptorRows, OfAFrameKeepsItsBackgroundKeypointsInOrder) {
  std::mt19937 rng(3);
  features::FeatureSet frame;
  frame.descriptors = randomBinary(5, rng);
  frame.keypoints.resize(5);
  frame.keypoints[0].class_id = features::kClassVehicle;  // movable: never queried
  frame.keypoints[3].class_id = features::kClassOtherMovable;
  const cv::Mat rows = placeDescriptorRows(frame, 2);
  ASSERT_EQ(rows.rows, 2);  // keypoints 1 and 2; 4 is over the limit
  EXPECT_EQ(cv::norm(rows.row(0), frame.descriptors.row(1), cv::NORM_HAMMING), 0.0);
  EXPECT_EQ(cv::norm(rows.row(1), frame.descriptors.row(2), cv::NORM_HAMMING), 0.0);
  EXPECT_EQ(placeDescriptorRows(frame, 100).rows, 3);
  EXPECT_TRUE(placeDescriptorRows(features::FeatureSet{}, 100).empty());
}

TEST(KeyFrameDatabase, MovableFeaturesOfAKeyFrameDoNotVote) {
  std::mt19937 rng(4);
  KeyFrameDatabase database;
  map::KeyFrame parked_car;  // a keyframe that saw only a vehicle
  parked_car.descriptors = randomBinary(50, rng);
  parked_car.keypoints.resize(50);
  for (auto& k : parked_car.keypoints)
    k.class_id = features::kClassVehicle;
  database.add(0, placeDescriptorRows(parked_car, 400));
  database.add(1, randomBinary(50, rng));
  EXPECT_EQ(database.numKeyFrames(), 1u);  // the empty rows added nothing
  const std::vector<PlaceScore> scores = database.query(parked_car.descriptors);
  for (const PlaceScore& s : scores)
    EXPECT_NE(s.id, 0);
}

}  // namespace
}  // namespace superdyna::loop

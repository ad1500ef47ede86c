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
  std::vector<map::KeyFrameId> ids;
  for (int k = 0; k < 40; ++k) {
    places.push_back(randomBinary(200, rng));
    database.add(k, k * kNsPerSecond / 2, places.back());
    ids.push_back(k);
  }
  // At 20 s the keyframes of the first 10 s (0..20) move from the held index into the graph.
  database.settle(20 * kNsPerSecond, ids);
  EXPECT_EQ(database.numHeldKeyFrames(), 19u);
  EXPECT_EQ(database.numKeyFrames(), 40u);
  EXPECT_EQ(database.numDescriptors(), 8000u);
  // Rows (32 bytes each) and the graph's links of the 4200 rows in it: 2 M = 32 links of 4 bytes
  // on the bottom layer, a few more on the upper ones, a level and an offset per row.
  EXPECT_GE(database.indexBytes(), 8000u * 32u + 4200u * 32u * 4u);
  EXPECT_LE(database.indexBytes(), 8000u * 32u + 4200u * 200u);
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
  // A held place (33) is found as well.
  const std::vector<PlaceScore> held = database.query(withFlippedBits(places[33], 20, rng));
  ASSERT_FALSE(held.empty());
  EXPECT_EQ(held.front().id, 33);
  EXPECT_NEAR(held.front().score, 1.0, 0.05);
}

TEST(KeyFrameDatabase, RetrievesFloatDescriptorsByCosine) {
  std::mt19937 rng(5);
  KeyFrameDatabase database;
  std::vector<cv::Mat> places;
  for (int k = 0; k < 30; ++k) {
    places.push_back(randomFloat(150, rng));
    database.add(100 + k, 0, places.back());
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

TEST(KeyFrameDatabase, HeldKeyFramesEnterTheGraphAfterTheHoldOnlyIfAlive) {
  std::mt19937 rng(6);
  KeyFrameDatabaseOptions options;
  options.hold_s = 10.0;
  KeyFrameDatabase database(options);
  const std::vector<cv::Mat> places = {randomBinary(200, rng), randomBinary(200, rng),
                                       randomBinary(200, rng)};
  database.add(0, 0, places[0]);
  database.add(1, 1 * kNsPerSecond, places[1]);
  database.add(2, 15 * kNsPerSecond, places[2]);
  // At 12 s keyframe 0 has been held for 12 s: into the graph; 1 was culled: forgotten; 2 stays.
  database.settle(12 * kNsPerSecond, {0, 2});
  EXPECT_EQ(database.numKeyFrames(), 2u);
  EXPECT_EQ(database.numHeldKeyFrames(), 1u);
  EXPECT_EQ(database.numDescriptors(), 400u);
  EXPECT_TRUE(database.query(places[1]).empty());
  for (const map::KeyFrameId id : {0, 2}) {
    const std::vector<PlaceScore> scores = database.query(places[static_cast<std::size_t>(id)]);
    ASSERT_EQ(scores.size(), 1u);
    EXPECT_EQ(scores.front().id, id);
    EXPECT_EQ(scores.front().votes, 200);
  }
}

TEST(KeyFrameDatabase, CulledKeyFramesStopVotingAndLeaveTheGraphOnceTheyDominate) {
  std::mt19937 rng(7);
  KeyFrameDatabaseOptions options;
  options.hold_s = 0.0;
  options.max_culled_share = 0.5;
  KeyFrameDatabase database(options);
  std::vector<cv::Mat> places;
  std::vector<map::KeyFrameId> alive;
  for (int k = 0; k < 40; ++k) {
    places.push_back(randomBinary(100, rng));
    database.add(k, k * kNsPerSecond, places.back());
    alive.push_back(k);
  }
  database.settle(40 * kNsPerSecond, alive);
  ASSERT_EQ(database.numHeldKeyFrames(), 0u);
  // 10 of 40 culled: they no longer vote, their rows wait for a rebuild.
  alive.erase(alive.begin(), alive.begin() + 10);
  database.settle(40 * kNsPerSecond, alive);
  EXPECT_EQ(database.numKeyFrames(), 30u);
  EXPECT_EQ(database.numDescriptors(), 4000u);
  EXPECT_EQ(database.rebuilds(), 0);
  EXPECT_TRUE(database.query(places[5]).empty());
  // 25 of 40 culled: more than half of the graph's rows, rebuilt with the living 15 only.
  alive.erase(alive.begin(), alive.begin() + 15);
  database.settle(40 * kNsPerSecond, alive);
  EXPECT_EQ(database.rebuilds(), 1);
  EXPECT_EQ(database.numDescriptors(), 1500u);
  EXPECT_TRUE(database.query(places[20]).empty());
  const std::vector<PlaceScore> scores = database.query(withFlippedBits(places[30], 10, rng));
  ASSERT_FALSE(scores.empty());
  EXPECT_EQ(scores.front().id, 30);
  EXPECT_EQ(scores.front().votes, 100);
}

TEST(KeyFrameDatabase, StaysBoundedByTheMapOverALongRun) {
  // A long run in which local mapping keeps every 10th keyframe and culls the others after 5 s:
  // the index holds a bounded multiple of the living keyframes' rows, not all it was given.
  std::mt19937 rng(8);
  KeyFrameDatabase database;  // default hold (10 s) and share (0.5)
  std::vector<map::KeyFrameId> alive;
  std::size_t most = 0;
  for (int k = 0; k < 600; ++k) {
    database.add(k, k * kNsPerSecond, randomBinary(50, rng));
    alive.push_back(k);
    std::erase_if(alive, [&](map::KeyFrameId id) { return id % 10 != 0 && id < k - 5; });
    database.settle(k * kNsPerSecond, alive);
    EXPECT_EQ(database.numKeyFrames(), alive.size());
    most = std::max(most, database.numDescriptors());
  }
  EXPECT_EQ(alive.size(), 66u);  // every 10th below 594, and 594..599
  // At most twice the graph's living rows (culled ones up to half) plus the held keyframes.
  EXPECT_LE(most, 2 * 50 * 60 + 50 * 6);
  EXPECT_LT(most, 600 * 50 / 4);
}

TEST(KeyFrameDatabase, RejectsAnotherDescriptorType) {
  std::mt19937 rng(1);
  KeyFrameDatabase database;
  database.add(0, 0, randomBinary(10, rng));
  EXPECT_THROW(database.add(1, 0, randomFloat(10, rng)), std::invalid_argument);
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
  database.add(0, 0, placeDescriptorRows(parked_car, 400));
  database.add(1, 0, randomBinary(50, rng));
  EXPECT_EQ(database.numKeyFrames(), 1u);  // the empty rows added nothing
  const std::vector<PlaceScore> scores = database.query(parked_car.descriptors);
  for (const PlaceScore& s : scores)
    EXPECT_NE(s.id, 0);
}

}  // namespace
}  // namespace superdyna::loop

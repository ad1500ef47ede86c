#include "superdyna/eval/association.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <tuple>

#include "superdyna/core/error.h"

namespace superdyna::eval {
namespace {

constexpr TimeNs kMs = kNsPerMillisecond;

AssociationOptions withTolerance(TimeNs max_diff_ns, TimeNs offset_ns = 0) {
  AssociationOptions options;
  options.max_diff_ns = max_diff_ns;
  options.offset_ns = offset_ns;
  return options;
}

/// TUM associate.py written out literally: all n * m candidates, sorted, accepted greedily.
std::vector<IndexPair> bruteForceAssociate(const std::vector<TimeNs>& gt,
                                           const std::vector<TimeNs>& est,
                                           const AssociationOptions& options) {
  std::vector<std::tuple<TimeNs, std::size_t, std::size_t>> candidates;
  for (std::size_t g = 0; g < gt.size(); ++g) {
    for (std::size_t e = 0; e < est.size(); ++e) {
      const TimeNs diff = std::abs(est[e] + options.offset_ns - gt[g]);
      if (diff <= options.max_diff_ns) candidates.emplace_back(diff, g, e);
    }
  }
  std::sort(candidates.begin(), candidates.end());
  std::vector<bool> gt_used(gt.size()), est_used(est.size());
  std::vector<IndexPair> pairs;
  for (const auto& [diff, g, e] : candidates) {
    if (gt_used[g] || est_used[e]) continue;
    gt_used[g] = est_used[e] = true;
    pairs.push_back({g, e});
  }
  std::sort(pairs.begin(), pairs.end(),
            [](const IndexPair& a, const IndexPair& b) { return a.gt_index < b.gt_index; });
  return pairs;
}

TEST(AssociationTest, OffsetShiftsEstimateTimes) {
  const std::vector<TimeNs> gt = {0, 100 * kMs, 200 * kMs, 300 * kMs};
  // The estimate clock runs 50 ms behind, with a few ms of jitter.
  const std::vector<TimeNs> est = {-50 * kMs + 2 * kMs, 50 * kMs - 3 * kMs, 150 * kMs,
                                   250 * kMs + 9 * kMs};
  EXPECT_TRUE(associateTimestamps(gt, est, withTolerance(10 * kMs)).empty());
  const auto pairs = associateTimestamps(gt, est, withTolerance(10 * kMs, 50 * kMs));
  const std::vector<IndexPair> expected = {{0, 0}, {1, 1}, {2, 2}, {3, 3}};
  EXPECT_EQ(pairs, expected);
}

TEST(AssociationTest, MaxDiffIsInclusiveAndDropsLargerGaps) {
  const std::vector<TimeNs> gt = {0, 100 * kMs, 200 * kMs};
  const std::vector<TimeNs> est = {10 * kMs, 111 * kMs, 190 * kMs};
  const auto pairs = associateTimestamps(gt, est, withTolerance(10 * kMs));
  const std::vector<IndexPair> expected = {{0, 0}, {2, 2}};  // 11 ms > 10 ms is dropped
  EXPECT_EQ(pairs, expected);
  EXPECT_EQ(associateTimestamps(gt, est, withTolerance(11 * kMs)).size(), 3u);
  EXPECT_EQ(associateTimestamps(gt, est, withTolerance(0)).size(), 0u);
}

TEST(AssociationTest, OneToOneGreedyBySmallestDifference) {
  // Both estimates are closest to ground truth 0; only the closer one gets it and the other has
  // nothing else within 10 ms.
  {
    const std::vector<TimeNs> gt = {0, 100 * kMs};
    const std::vector<TimeNs> est = {1 * kMs, 3 * kMs};
    const std::vector<IndexPair> expected = {{0, 0}};
    EXPECT_EQ(associateTimestamps(gt, est, withTolerance(10 * kMs)), expected);
  }
  // est 6 ms takes gt 8 ms first (2 ms); est 5 ms then falls back to gt 0 (5 ms), although its
  // nearest ground truth was gt 8 ms.
  {
    const std::vector<TimeNs> gt = {0, 8 * kMs};
    const std::vector<TimeNs> est = {5 * kMs, 6 * kMs};
    const std::vector<IndexPair> expected = {{0, 0}, {1, 1}};
    EXPECT_EQ(associateTimestamps(gt, est, withTolerance(10 * kMs)), expected);
  }
  // Greedy matches may cross in time; the output is still sorted by ground-truth time.
  {
    const std::vector<TimeNs> gt = {5 * kMs, 6 * kMs};
    const std::vector<TimeNs> est = {0, 5 * kMs};
    const std::vector<IndexPair> expected = {{0, 1}, {1, 0}};
    EXPECT_EQ(associateTimestamps(gt, est, withTolerance(10 * kMs)), expected);
  }
}

TEST(AssociationTest, TiesResolvedByEarlierGroundTruth) {
  const std::vector<TimeNs> gt = {0, 10 * kMs};
  const std::vector<TimeNs> est = {5 * kMs};
  const std::vector<IndexPair> expected = {{0, 0}};
  EXPECT_EQ(associateTimestamps(gt, est, withTolerance(10 * kMs)), expected);
}

TEST(AssociationTest, MatchesBruteForceOnRandomStreams) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<TimeNs> step(1 * kMs, 40 * kMs);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<TimeNs> gt, est;
    TimeNs t = 0;
    for (int i = 0; i < 200; ++i)
      gt.push_back(t += step(rng));
    t = 3 * kMs;
    for (int i = 0; i < 150; ++i)
      est.push_back(t += step(rng));
    const auto options = withTolerance(15 * kMs, (trial % 5 - 2) * kMs);
    EXPECT_EQ(associateTimestamps(gt, est, options), bruteForceAssociate(gt, est, options))
        << "trial " << trial;
  }
}

TEST(AssociationTest, GathersMatchedPoses) {
  Trajectory gt, est;
  for (int i = 0; i < 5; ++i) {
    gt.push_back({i * 100 * kMs, SE3d(Eigen::Matrix3d::Identity(), Eigen::Vector3d(i, 0, 0))});
    est.push_back(
        {i * 100 * kMs + 3 * kMs, SE3d(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, i, 0))});
  }
  est.erase(est.begin() + 2);
  const AssociatedPoses matched = associate(gt, est, AssociationOptions{});
  ASSERT_EQ(matched.size(), 4u);
  EXPECT_EQ(matched.t_ns[2], 300 * kMs);  // ground-truth time
  EXPECT_DOUBLE_EQ(matched.gt[2].t.x(), 3.0);
  EXPECT_DOUBLE_EQ(matched.est[2].t.y(), 3.0);
}

TEST(AssociationTest, RejectsBadOptionsAndUnsortedTimes) {
  EXPECT_THROW(associateTimestamps({0}, {0}, withTolerance(-1)), OptionError);
  EXPECT_THROW(associateTimestamps({0, 0}, {0}, withTolerance(1)), InputError);
  EXPECT_THROW(associateTimestamps({0}, {5, 2}, withTolerance(1)), InputError);
}

}  // namespace
}  // namespace superdyna::eval

#pragma once
// Descriptor matching for binary (ORB) features: Hamming distance, brute-force mutual nearest
// neighbours with a ratio test, projection-guided search through a grid index of keypoints, and
// ORB-SLAM's rotation-consistency check.
//
// All matchers are deterministic (ties go to the lower index) and return matches ordered by
// query index.

#include <Eigen/Core>
#include <climits>
#include <cstdint>
#include <vector>

#include "superdyna/features/feature_set.h"

namespace superdyna::features {

/// Number of differing bits between two descriptors of `bytes` bytes.
int hammingDistance(const std::uint8_t* a, const std::uint8_t* b, int bytes);
/// Hamming distance of two single-row CV_8UC1 descriptors of equal length.
int hammingDistance(const cv::Mat& a, const cv::Mat& b);

/// A correspondence between query feature `query` and train feature `train`.
struct Match {
  int query = -1;
  int train = -1;
  int distance = 0;  ///< Hamming distance [bits].
};

/// The rotation-consistency check: a histogram of the keypoint angle differences of the
/// matches; only matches in the fullest bins survive.
struct OrientationCheckOptions {
  int bins = 30;      ///< Histogram bins over 360 degrees (12 degrees each), in [1, 360].
  int keep_bins = 3;  ///< The fullest bins kept, in [1, bins].
  /// Bins other than the fullest are kept only with at least this fraction of its count, [0, 1].
  double min_bin_fraction = 0.1;

  void validate() const;
};

/// The matches whose angle difference (query angle - train angle) falls into one of the
/// keep_bins fullest bins. Bins are centred on multiples of 360 / bins degrees (bin 0 holds
/// differences within half a bin of 0). Matches involving a keypoint without angle (< 0) are
/// dropped. Order is preserved.
std::vector<Match> filterByOrientation(const std::vector<Match>& matches,
                                       const std::vector<Keypoint>& query,
                                       const std::vector<Keypoint>& train,
                                       const OrientationCheckOptions& options = {});

struct BruteForceMatchOptions {
  int max_distance = 64;  ///< Largest accepted Hamming distance [bits], >= 0.
  /// Lowe's ratio test: best < ratio * second best (over distinct train features); in (0, 1],
  /// 1 disables it.
  double ratio = 0.8;
  bool mutual = true;  ///< Keep a match only if the query is also the train's nearest neighbour.
  bool check_orientation = false;  ///< Apply filterByOrientation() to the result.
  OrientationCheckOptions orientation;

  void validate() const;
};

/// Exhaustive matching of binary descriptors. Throws InputError unless both sets are kBinary
/// with equal descriptor lengths.
std::vector<Match> matchBruteForce(const FeatureSet& query, const FeatureSet& train,
                                   const BruteForceMatchOptions& options = {});

/// A uniform grid of keypoint indices over the image, for radius queries.
class KeypointGrid {
 public:
  /// Copies the positions and octaves. `cell_size_px` > 0 (else OptionError); keypoints outside
  /// the image fall into the nearest border cell.
  KeypointGrid(const std::vector<Keypoint>& keypoints, cv::Size image_size, int cell_size_px = 20);

  /// Indices (ascending) of the keypoints within `radius_px` (Euclidean, inclusive) of
  /// `center`, with octave in [min_octave, max_octave].
  std::vector<int> within(const Eigen::Vector2d& center, double radius_px, int min_octave = 0,
                          int max_octave = INT_MAX) const;
  /// Number of keypoints indexed.
  std::size_t size() const { return pixels_.size(); }

 private:
  std::vector<Eigen::Vector2d> pixels_;
  std::vector<int> octaves_;
  int cell_size_;
  int cols_, rows_;
  std::vector<std::vector<int>> cells_;
};

struct ProjectionMatchOptions {
  double radius_px = 15.0;  ///< Search radius around each predicted pixel [px], > 0.
  int max_distance = 100;   ///< Largest accepted Hamming distance [bits], >= 0.
  /// best < ratio * second best among the candidates in the radius; in (0, 1], 1 disables it.
  double ratio = 0.9;
  /// Candidates must satisfy |octave - query octave| <= this; < 0 accepts every octave.
  int max_octave_difference = -1;
  bool check_orientation = true;  ///< Apply filterByOrientation() to the result.
  OrientationCheckOptions orientation;

  void validate() const;
};

/// For each query feature i with a finite predicted pixel predicted[i] (e.g. a map point
/// projected with the predicted pose), the train feature within the radius with the smallest
/// distance, subject to max_distance and the ratio test. Each train feature is matched at most
/// once (to its closest query). `train_grid` must index train.keypoints. Throws InputError when
/// predicted.size() != query.size() or the descriptors are not comparable kBinary ones.
std::vector<Match> matchByProjection(const FeatureSet& query,
                                     const std::vector<Eigen::Vector2d>& predicted,
                                     const FeatureSet& train, const KeypointGrid& train_grid,
                                     const ProjectionMatchOptions& options = {});

}  // namespace superdyna::features

#pragma once
// Descriptor matching: brute-force mutual nearest neighbours with a ratio test, projection-guided
// search through a grid index of keypoints, and ORB-SLAM's rotation-consistency check. Both kinds
// of descriptors are handled (FeatureSet::descriptor_type): binary ones (ORB) by Hamming distance
// [bits], float ones (XFeat, SuperPoint: unit-norm rows) by Euclidean distance (in [0, 2]).
//
// Class-wise matching: with `same_class_only` a query keypoint is compared only with train
// keypoints of its semantic class (Keypoint::class_id), so that a feature on a car never pairs
// with one on a wall or a pedestrian.
//
// All matchers are deterministic (ties go to the lower index) and return matches ordered by
// query index.

#include <Eigen/Core>
#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <vector>

#include "superdyna/features/feature_set.h"

namespace superdyna::features {

/// Number of differing bits between two descriptors of `bytes` bytes.
int hammingDistance(const std::uint8_t* a, const std::uint8_t* b, int bytes);
/// Hamming distance of two single-row CV_8UC1 descriptors of equal length.
int hammingDistance(const cv::Mat& a, const cv::Mat& b);

/// Euclidean distance of two float descriptors of `length` floats.
float l2Distance(const float* a, const float* b, int length);

/// Distances between the descriptor rows of two feature sets of the same descriptor type and
/// length: Hamming [bits] for kBinary, Euclidean for kFloat.
class DescriptorMetric {
 public:
  /// Throws InputError naming `who` unless the sets are valid, of one descriptor type and (when
  /// both are non-empty) of one descriptor length.
  DescriptorMetric(const FeatureSet& query, const FeatureSet& train, const char* who);

  /// Distance of query row i and train row j.
  double operator()(int i, int j) const {
    if (type_ == DescriptorType::kBinary) {
      return hammingDistance(query_->ptr<std::uint8_t>(i), train_->ptr<std::uint8_t>(j), length_);
    }
    return l2Distance(query_->ptr<float>(i), train_->ptr<float>(j), length_);
  }
  DescriptorType type() const { return type_; }
  /// The bound that applies to this type: max_hamming [bits] or max_l2.
  double bound(int max_hamming, double max_l2) const {
    return type_ == DescriptorType::kBinary ? max_hamming : max_l2;
  }

 private:
  const cv::Mat* query_;
  const cv::Mat* train_;
  DescriptorType type_;
  int length_;
};

/// Distance of two single-row descriptors of one OpenCV type: Hamming for CV_8UC1, Euclidean for
/// CV_32FC1. Throws InputError for other types or different lengths.
double descriptorDistance(const cv::Mat& a, const cv::Mat& b);

/// Whether every keypoint of the set has an orientation (angle >= 0); false when empty. Learned
/// extractors give none, and the rotation-consistency check is then skipped.
bool hasOrientation(const FeatureSet& features);

/// A correspondence between query feature `query` and train feature `train`.
struct Match {
  int query = -1;
  int train = -1;
  double distance = 0.0;  ///< Hamming distance [bits] or Euclidean distance (DescriptorMetric).
};

/// The rotation-consistency check: a histogram of the keypoint angle differences of the
/// matches; only matches in the fullest bins survive.
struct OrientationCheckOptions {
  int bins = 30;      ///< Histogram bins over 360 degrees (12 degrees each), in [1, 360].
  int keep_bins = 3;  ///< The fullest bins kept, in [1, bins].
  /// Bins other than the fullest are kept only with at least this fraction of its count, [0, 1].
  double min_bin_fraction = 0.1;

  void validate() const;
  bool operator==(const OrientationCheckOptions&) const = default;
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
  int max_distance = 64;         ///< Largest accepted Hamming distance [bits], >= 0.
  double max_l2_distance = 1.0;  ///< Largest accepted Euclidean distance (float), >= 0.
  /// Lowe's ratio test: best < ratio * second best (over distinct train features); in (0, 1],
  /// 1 disables it.
  double ratio = 0.8;
  bool mutual = true;  ///< Keep a match only if the query is also the train's nearest neighbour.
  /// Apply filterByOrientation() to the result (skipped when a set has no orientations).
  bool check_orientation = false;
  bool same_class_only = false;  ///< Compare only keypoints of one class_id (file comment).
  OrientationCheckOptions orientation;

  void validate() const;
  bool operator==(const BruteForceMatchOptions&) const = default;
};

/// Exhaustive matching. Throws InputError unless both sets have one descriptor type and length.
std::vector<Match> matchBruteForce(const FeatureSet& query, const FeatureSet& train,
                                   const BruteForceMatchOptions& options = {});

/// A uniform grid of keypoint indices over the image, for radius queries.
class KeypointGrid {
 public:
  /// Copies the positions and octaves. `cell_size_px` > 0 (else OptionError); keypoints outside
  /// the image fall into the nearest border cell.
  KeypointGrid(const std::vector<Keypoint>& keypoints, cv::Size image_size, int cell_size_px = 20);
  /// As above, but only the keypoints i with `include[i]` != 0 are found by queries; indices
  /// still refer to `keypoints` (so a subset is searched without copying its descriptors).
  /// `include` holds one entry per keypoint (else InputError).
  KeypointGrid(const std::vector<Keypoint>& keypoints, cv::Size image_size, int cell_size_px,
               const std::vector<char>& include);

  /// Indices (ascending) of the keypoints within `radius_px` (Euclidean, inclusive) of
  /// `center`, with octave in [min_octave, max_octave].
  std::vector<int> within(const Eigen::Vector2d& center, double radius_px, int min_octave = 0,
                          int max_octave = INT_MAX) const;
  /// Calls `visit(index)` for each keypoint within() would return, in cell order (not sorted);
  /// no allocation, for the hot loops of the matchers.
  template <class Visit>
  void forEachWithin(const Eigen::Vector2d& center, double radius_px, int min_octave,
                     int max_octave, Visit&& visit) const;
  /// Number of keypoints the indices refer to (every keypoint given, included or not).
  std::size_t size() const { return pixels_.size(); }

 private:
  std::vector<Eigen::Vector2d> pixels_;
  std::vector<int> octaves_;
  int cell_size_;
  int cols_, rows_;
  std::vector<std::vector<int>> cells_;
};

template <class Visit>
void KeypointGrid::forEachWithin(const Eigen::Vector2d& center, double radius_px, int min_octave,
                                 int max_octave, Visit&& visit) const {
  if (!(radius_px >= 0.0) || !center.allFinite()) return;
  const auto cell = [this](double v, int count) {
    return std::clamp(static_cast<int>(std::floor(v / cell_size_)), 0, count - 1);
  };
  const int c0 = cell(center.x() - radius_px, cols_), c1 = cell(center.x() + radius_px, cols_);
  const int r0 = cell(center.y() - radius_px, rows_), r1 = cell(center.y() + radius_px, rows_);
  const double radius2 = radius_px * radius_px;
  for (int r = r0; r <= r1; ++r) {
    for (int c = c0; c <= c1; ++c) {
      for (const int i : cells_[static_cast<std::size_t>(r * cols_ + c)]) {
        const auto k = static_cast<std::size_t>(i);
        if (octaves_[k] < min_octave || octaves_[k] > max_octave) continue;
        if ((pixels_[k] - center).squaredNorm() <= radius2) visit(i);
      }
    }
  }
}

struct ProjectionMatchOptions {
  double radius_px = 15.0;       ///< Search radius around each predicted pixel [px], > 0.
  int max_distance = 100;        ///< Largest accepted Hamming distance [bits], >= 0.
  double max_l2_distance = 1.0;  ///< Largest accepted Euclidean distance (float), >= 0.
  /// best < ratio * second best among the candidates in the radius; in (0, 1], 1 disables it.
  double ratio = 0.9;
  /// Candidates' octaves lie in [query octave + min_octave_offset, query octave +
  /// max_octave_offset], offsets within [-kMaxOctaveOffset, kMaxOctaveOffset]; the defaults accept
  /// every octave. ORB-SLAM's local-map search: -1 and 0 about the point's predicted octave
  /// (map::predictedOctave rounds up).
  static constexpr int kMaxOctaveOffset = 100;
  int min_octave_offset = -kMaxOctaveOffset;
  int max_octave_offset = kMaxOctaveOffset;
  /// The radius grows with the query's octave: radius_px * radius_octave_scale^octave, >= 1
  /// (ORB-SLAM: the pyramid's scale factor, as a coarser keypoint is located less precisely); 1
  /// keeps it fixed.
  double radius_octave_scale = 1.0;
  /// The ratio test compares the best candidate only with the others at the best's octave
  /// (ORB-SLAM): the same corner detected at two pyramid levels is one candidate, not an ambiguity.
  bool ratio_within_octave = false;
  /// Apply filterByOrientation() to the result (skipped when a set has no orientations).
  bool check_orientation = true;
  OrientationCheckOptions orientation;
  bool same_class_only = false;  ///< Candidates must share the query's class_id (file comment).

  void validate() const;
  bool operator==(const ProjectionMatchOptions&) const = default;
};

/// For each query feature i with a finite predicted pixel predicted[i] (e.g. a map point
/// projected with the predicted pose), the train feature within the radius with the smallest
/// distance, subject to max_distance and the ratio test. Each train feature is matched at most
/// once (to its closest query). `train_grid` must index train.keypoints. Throws InputError when
/// predicted.size() != query.size() or the descriptors are not comparable.
std::vector<Match> matchByProjection(const FeatureSet& query,
                                     const std::vector<Eigen::Vector2d>& predicted,
                                     const FeatureSet& train, const KeypointGrid& train_grid,
                                     const ProjectionMatchOptions& options = {});

}  // namespace superdyna::features

#pragma once
// Place recognition without a vocabulary: a nearest-neighbour voting index over the keyframes'
// descriptors (faiss, exact search, no training). Each keyframe adds its place descriptors (see
// placeDescriptorRows()); a query descriptor votes once for every keyframe among the owners of its
// k nearest indexed descriptors (within a distance bound), and a keyframe's score is its votes
// divided by the number of query descriptors (the share of the query it explains, in [0, 1]).
//
// Binary descriptors (CV_8UC1 rows, ORB: 32 bytes) go into a Hamming index; float ones (CV_32FC1,
// XFeat, SuperPoint) are L2-normalised into an inner-product index. The first keyframe added fixes
// the type; later keyframes of another type are an std::invalid_argument. faiss runs in the
// caller's thread only (one OpenMP thread), so results do not depend on the machine's cores and
// the deterministic pipeline stays bit-identical.

#include <cstddef>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "superdyna/features/feature_set.h"
#include "superdyna/map/keyframe.h"

namespace superdyna::loop {

struct KeyFrameDatabaseOptions {
  int neighbours = 4;  ///< k nearest indexed descriptors per query descriptor, >= 1.
  /// Place descriptors per keyframe (indexed and queried), >= 1: those observing map points,
  /// then the others, in keypoint order.
  int max_descriptors = 400;
  int max_hamming = 60;          ///< Binary: neighbours farther than this [bits] do not vote.
  double min_similarity = 0.75;  ///< Float: neighbours with a smaller cosine do not vote.
  /// Index: 0 = exact search (cost linear in the map: on 2 cores 0.26 s per ORB query at 100
  /// keyframes, 9 s at 3600, bench/loop_bench.cc); > 0 = a graph index (faiss HNSW, 16 links per
  /// descriptor) searched with this candidate-list breadth (efSearch, >= neighbours): cost
  /// logarithmic in the map, nearest neighbours approximate. Built in one thread: deterministic.
  int hnsw_search = 64;
  /// Throws OptionError naming the first invalid field (prefix "loop.database_").
  void validate() const;
  bool operator==(const KeyFrameDatabaseOptions&) const = default;
};

/// A keyframe that received votes.
struct PlaceScore {
  map::KeyFrameId id = map::kNoKeyFrame;
  int votes = 0;
  double score = 0.0;  ///< votes / query descriptors.
};

/// The descriptor rows of a keyframe that take part in place recognition: keypoints labelled
/// background (class_id 0; features on movable or moving objects never vote nor get votes),
/// those observing a map point first, at most `max_rows`. Empty without descriptors.
cv::Mat placeDescriptorRows(const map::KeyFrame& keyframe, int max_rows);
/// The same for a frame (no map points yet): its background keypoints in order, at most
/// `max_rows`.
cv::Mat placeDescriptorRows(const features::FeatureSet& features, int max_rows);

class KeyFrameDatabase {
 public:
  explicit KeyFrameDatabase(const KeyFrameDatabaseOptions& options = {});
  ~KeyFrameDatabase();
  KeyFrameDatabase(const KeyFrameDatabase&) = delete;
  KeyFrameDatabase& operator=(const KeyFrameDatabase&) = delete;

  /// Indexes the rows (placeDescriptorRows()) as keyframe `id`'s. Empty rows add nothing.
  void add(map::KeyFrameId id, const cv::Mat& rows);
  /// Every keyframe with at least one vote from `rows`, by decreasing votes (ties: increasing id).
  std::vector<PlaceScore> query(const cv::Mat& rows) const;

  std::size_t numKeyFrames() const { return keyframes_; }
  std::size_t numDescriptors() const { return owners_.size(); }
  /// Bytes of the stored descriptors (the index's memory, up to small bookkeeping).
  std::size_t descriptorBytes() const;
  void clear();

 private:
  struct Index;
  std::vector<std::vector<map::KeyFrameId>> neighbourOwners(const cv::Mat& rows) const;

  KeyFrameDatabaseOptions options_;
  std::unique_ptr<Index> index_;
  std::vector<map::KeyFrameId> owners_;  ///< Keyframe of each indexed row.
  std::size_t keyframes_ = 0;
};

}  // namespace superdyna::loop

#pragma once
// Place recognition without a vocabulary: a nearest-neighbour voting index over the keyframes'
// descriptors (faiss, no training). Each keyframe adds its place descriptors (see
// placeDescriptorRows()); a query descriptor votes once for every keyframe among the owners of its
// k nearest indexed descriptors (within a distance bound), and a keyframe's score is its votes
// divided by the number of query descriptors (the share of the query it explains, in [0, 1]).
//
// Binary descriptors (CV_8UC1 rows, ORB: 32 bytes) go into a Hamming index; float ones (CV_32FC1,
// XFeat, SuperPoint) are L2-normalised into an inner-product index. The first keyframe added fixes
// the type; later keyframes of another type are an std::invalid_argument. faiss runs in the
// caller's thread only (one OpenMP thread), so results do not depend on the machine's cores and
// the deterministic pipeline stays bit-identical.
//
// Bounded by the map, not by the run: a graph index (HNSW) cannot remove entries, and local
// mapping culls most new keyframes within seconds. So a new keyframe's rows are first *held* in a
// small exact index searched beside the graph; settle() moves those held for hold_s into the graph
// when their keyframe is still in the map and drops culled ones, and rebuilds the graph from the
// rows of the living keyframes once culled keyframes' rows make up more than max_culled_share of
// it (culled keyframes never vote in between). Memory then follows the map's keyframes: a 30-min
// revisiting run no longer grows the index by every keyframe it ever made.

#include <cstddef>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "superdyna/core/time.h"
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
  /// Index: 0 = exact search (cost linear in the map: 140 ms CPU per ORB query at 400 keyframes,
  /// bench/loop_bench.cc); > 0 = a graph index (faiss HNSW, 16 links per
  /// descriptor) searched with this candidate-list breadth (efSearch, >= neighbours): cost
  /// logarithmic in the map, nearest neighbours approximate. Built in one thread: deterministic.
  int hnsw_search = 64;
  /// A new keyframe's rows stay in the held (exact) index this long [s] before settle() moves
  /// them into the graph, >= 0: most keyframes local mapping culls never reach it.
  double hold_s = 10.0;
  /// settle() rebuilds the graph index without culled keyframes' rows once these are more than
  /// this share of its rows, in (0, 1].
  double max_culled_share = 0.5;
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

  /// Adds the rows (placeDescriptorRows()) of keyframe `id`, made at `t_ns`, to the held index.
  /// Empty rows add nothing.
  void add(map::KeyFrameId id, TimeNs t_ns, const cv::Mat& rows);
  /// Brings the index up to date with the map: `alive` are the map's keyframe ids, sorted. Held
  /// keyframes made at or before now_ns - hold_s move into the graph index if alive; culled ones
  /// are forgotten (held: at once; in the graph: they stop voting, and their rows go when the
  /// graph is rebuilt, see max_culled_share).
  void settle(TimeNs now_ns, const std::vector<map::KeyFrameId>& alive);
  /// Every keyframe with at least one vote from `rows`, by decreasing votes (ties: increasing id).
  std::vector<PlaceScore> query(const cv::Mat& rows) const;

  /// Keyframes that can receive votes (held, or in the graph and not culled).
  std::size_t numKeyFrames() const { return held_.size() + graph_rows_of_.size(); }
  std::size_t numHeldKeyFrames() const { return held_.size(); }
  /// Descriptor rows stored (held and in the graph, culled ones until the next rebuild).
  std::size_t numDescriptors() const;
  /// Memory of the two indices [bytes]: the stored rows and the graph's links (with M = 16 the
  /// links are about 150 bytes per row, four times an ORB row).
  std::size_t indexBytes() const;
  /// Rebuilds of the graph index so far.
  int rebuilds() const { return rebuilds_; }
  void clear();

 private:
  class RowIndex;
  struct Held {
    map::KeyFrameId id = map::kNoKeyFrame;
    TimeNs t_ns = 0;
    cv::Mat rows;  ///< As indexed (float rows normalised).
  };
  /// The query's rows, held k nearest merged with the graph's, as the owners they vote for.
  std::vector<std::vector<map::KeyFrameId>> neighbourOwners(const cv::Mat& rows) const;
  void createIndexes(const cv::Mat& rows);
  void rebuildHeldIndex();
  void rebuildGraph();
  bool nearEnough(double distance) const;

  KeyFrameDatabaseOptions options_;
  int type_ = -1;  ///< CV_8UC1 or CV_32FC1, fixed by the first keyframe.
  int cols_ = 0;
  std::unique_ptr<RowIndex> graph_;
  std::vector<map::KeyFrameId> graph_owners_;  ///< Keyframe of each graph row.
  /// Rows in the graph per living keyframe; a culled keyframe's rows stay until rebuildGraph().
  std::map<map::KeyFrameId, int> graph_rows_of_;
  std::size_t culled_graph_rows_ = 0;
  std::vector<Held> held_;  ///< By increasing t_ns.
  std::unique_ptr<RowIndex> held_index_;
  std::vector<map::KeyFrameId> held_owners_;  ///< Keyframe of each held index row.
  int rebuilds_ = 0;
};

}  // namespace superdyna::loop

#include "superdyna/loop/keyframe_database.h"

#include <faiss/IndexBinaryHNSW.h>
#include <faiss/IndexFlat.h>
#include <faiss/IndexHNSW.h>
#include <omp.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <map>
#include <stdexcept>

#include "superdyna/core/error.h"
#include "superdyna/features/feature_set.h"

namespace superdyna::loop {

void KeyFrameDatabaseOptions::validate() const {
  if (neighbours < 1) throw OptionError("loop.database_neighbours", "must be >= 1");
  if (max_descriptors < 1) throw OptionError("loop.database_max_descriptors", "must be >= 1");
  if (max_hamming < 0) throw OptionError("loop.database_max_hamming", "must be >= 0");
  if (!(min_similarity >= -1.0 && min_similarity <= 1.0)) {
    throw OptionError("loop.database_min_similarity", "must be in [-1, 1]");
  }
  if (hnsw_search != 0 && hnsw_search < neighbours) {
    throw OptionError("loop.database_hnsw_search", "must be 0 (exact) or >= database_neighbours");
  }
  if (!(hold_s >= 0.0)) throw OptionError("loop.database_hold_s", "must be >= 0");
  if (!(max_culled_share > 0.0 && max_culled_share <= 1.0)) {
    throw OptionError("loop.database_max_culled_share", "must be in (0, 1]");
  }
}

namespace {

/// The first max_rows of the descriptor rows `selected`, in that order.
cv::Mat selectedRows(const cv::Mat& descriptors, std::vector<int> selected, int max_rows) {
  if (static_cast<int>(selected.size()) > max_rows) {
    selected.resize(static_cast<std::size_t>(max_rows));
  }
  cv::Mat rows(static_cast<int>(selected.size()), descriptors.cols, descriptors.type());
  for (std::size_t k = 0; k < selected.size(); ++k) {
    descriptors.row(selected[k]).copyTo(rows.row(static_cast<int>(k)));
  }
  return rows;
}

}  // namespace

cv::Mat placeDescriptorRows(const map::KeyFrame& keyframe, int max_rows) {
  if (keyframe.descriptors.empty()) return {};
  std::vector<int> with_point;
  std::vector<int> without_point;
  for (std::size_t i = 0; i < keyframe.keypoints.size(); ++i) {
    if (keyframe.keypoints[i].class_id != features::kClassBackground) continue;
    const bool observed =
        i < keyframe.map_points.size() && keyframe.map_points[i] != map::kNoMapPoint;
    (observed ? with_point : without_point).push_back(static_cast<int>(i));
  }
  with_point.insert(with_point.end(), without_point.begin(), without_point.end());
  return selectedRows(keyframe.descriptors, std::move(with_point), max_rows);
}

cv::Mat placeDescriptorRows(const features::FeatureSet& features, int max_rows) {
  if (features.descriptors.empty()) return {};
  std::vector<int> background;
  for (std::size_t i = 0; i < features.keypoints.size(); ++i) {
    if (features.keypoints[i].class_id == features::kClassBackground) {
      background.push_back(static_cast<int>(i));
    }
  }
  return selectedRows(features.descriptors, std::move(background), max_rows);
}

namespace {

cv::Mat normalizedRows(const cv::Mat& rows) {
  cv::Mat out = rows.clone();
  for (int r = 0; r < out.rows; ++r) {
    const double norm = cv::norm(out.row(r));
    if (norm > 0.0) out.row(r) /= norm;
  }
  return out;
}

constexpr int kHnswLinks = 16;         ///< HNSW's M: links per descriptor and layer.
constexpr int kHnswConstruction = 40;  ///< HNSW's efConstruction.

/// faiss in the calling thread only: deterministic and no oversubscription of the pipeline's cores.
void useOneThread() {
  omp_set_num_threads(1);
}

using Label = faiss::Index::idx_t;  ///< A row of a faiss index.

/// One of a query row's nearest indexed rows.
struct Neighbour {
  double distance = 0.0;  ///< Hamming bits, or 1 - cosine.
  map::KeyFrameId owner = map::kNoKeyFrame;
};

/// Hamming distances of `query` to each of `n` rows of `bytes` bytes.
[[gnu::always_inline]] inline void hammingDistancesOf(const std::uint8_t* query,
                                                      const std::uint8_t* rows, std::size_t n,
                                                      int bytes, std::int32_t* out) {
  for (std::size_t r = 0; r < n; ++r) {
    const std::uint8_t* row = rows + r * static_cast<std::size_t>(bytes);
    int bits = 0;
    int b = 0;
    for (; b + 8 <= bytes; b += 8) {
      std::uint64_t x = 0;
      std::uint64_t y = 0;
      std::memcpy(&x, query + b, 8);
      std::memcpy(&y, row + b, 8);
      bits += __builtin_popcountll(x ^ y);
    }
    for (; b < bytes; ++b)
      bits += __builtin_popcount(static_cast<unsigned>(query[b] ^ row[b]));
    out[r] = bits;
  }
}

#if defined(__x86_64__) || defined(__i386__)
/// The same compiled for the CPU's popcount instruction.
[[gnu::target("popcnt")]] void hammingDistancesPopcnt(const std::uint8_t* query,
                                                      const std::uint8_t* rows, std::size_t n,
                                                      int bytes, std::int32_t* out) {
  hammingDistancesOf(query, rows, n, bytes, out);
}

void hammingDistancesPortable(const std::uint8_t* query, const std::uint8_t* rows, std::size_t n,
                              int bytes, std::int32_t* out) {
  hammingDistancesOf(query, rows, n, bytes, out);
}

/// Uses the popcount instruction where the CPU has one: Debian's faiss is built for the baseline
/// x86-64, which counts bits in software - its exact binary search took 3x as long here. Chosen
/// at run time by a plain branch, not an ifunc (target_clones): ThreadSanitizer builds crash
/// resolving ifuncs at start-up.
void hammingDistances(const std::uint8_t* query, const std::uint8_t* rows, std::size_t n, int bytes,
                      std::int32_t* out) {
  static const bool has_popcount = __builtin_cpu_supports("popcnt");
  if (has_popcount) {
    hammingDistancesPopcnt(query, rows, n, bytes, out);
  } else {
    hammingDistancesPortable(query, rows, n, bytes, out);
  }
}
#else
void hammingDistances(const std::uint8_t* query, const std::uint8_t* rows, std::size_t n, int bytes,
                      std::int32_t* out) {
  hammingDistancesOf(query, rows, n, bytes, out);
}
#endif

/// Exact k-nearest search over binary rows (Hamming), ties to the earlier row.
class HammingRows {
 public:
  explicit HammingRows(int bytes) : bytes_(bytes) {}

  void add(const cv::Mat& rows) {
    const std::size_t size = static_cast<std::size_t>(rows.rows) * static_cast<std::size_t>(bytes_);
    data_.insert(data_.end(), rows.ptr<std::uint8_t>(0), rows.ptr<std::uint8_t>(0) + size);
  }

  std::size_t size() const { return data_.size() / static_cast<std::size_t>(bytes_); }
  std::size_t bytes() const { return data_.size(); }

  /// Fills row q's k slots of distances / labels (n x k, preset to -1 labels).
  void search(const cv::Mat& rows, int k, std::vector<double>& distances,
              std::vector<Label>& labels) const {
    std::vector<std::int32_t> bits(size());
    const std::size_t kk = static_cast<std::size_t>(k);
    for (int q = 0; q < rows.rows; ++q) {
      hammingDistances(rows.ptr<std::uint8_t>(q), data_.data(), bits.size(), bytes_, bits.data());
      double* best_distance = distances.data() + static_cast<std::size_t>(q) * kk;
      Label* best_label = labels.data() + static_cast<std::size_t>(q) * kk;
      std::size_t filled = 0;
      for (std::size_t r = 0; r < bits.size(); ++r) {
        const double d = bits[r];
        if (filled == kk && d >= best_distance[kk - 1]) continue;
        std::size_t slot = filled < kk ? filled++ : kk - 1;
        while (slot > 0 && best_distance[slot - 1] > d) {
          best_distance[slot] = best_distance[slot - 1];
          best_label[slot] = best_label[slot - 1];
          --slot;
        }
        best_distance[slot] = d;
        best_label[slot] = static_cast<Label>(r);
      }
    }
  }

  void row(Label label, std::uint8_t* out) const {
    const std::size_t start = static_cast<std::size_t>(label) * static_cast<std::size_t>(bytes_);
    std::memcpy(out, data_.data() + start, static_cast<std::size_t>(bytes_));
  }

 private:
  int bytes_;
  std::vector<std::uint8_t> data_;
};

}  // namespace

/// One index of rows of one type: binary (Hamming) or float (inner product of unit rows), exact
/// (hnsw_search 0; binary rows in HammingRows) or a faiss graph.
class KeyFrameDatabase::RowIndex {
 public:
  RowIndex(int type, int cols, int hnsw_search) {
    if (type == CV_8UC1 && hnsw_search == 0) {
      hamming_ = std::make_unique<HammingRows>(cols);
    } else if (type == CV_8UC1) {
      binary_ = binaryGraph(8 * cols, hnsw_search);
    } else {
      dense_ = denseIndex(cols, hnsw_search);
    }
  }

  /// Continuous rows of the index's type (float rows normalised).
  void add(const cv::Mat& rows) {
    useOneThread();
    if (hamming_) {
      hamming_->add(rows);
    } else if (binary_) {
      binary_->add(rows.rows, rows.ptr<std::uint8_t>(0));
    } else {
      dense_->add(rows.rows, rows.ptr<float>(0));
    }
  }

  /// Memory of the rows and, for a graph, of its links.
  std::size_t bytes() const {
    if (hamming_) return hamming_->bytes();
    if (binary_) {
      const auto* graph = dynamic_cast<const faiss::IndexBinaryHNSW*>(binary_.get());
      return static_cast<std::size_t>(binary_->ntotal) *
                 static_cast<std::size_t>(binary_->code_size) +
             (graph != nullptr ? linkBytes(graph->hnsw) : 0);
    }
    const std::size_t rows = static_cast<std::size_t>(dense_->ntotal) *
                             static_cast<std::size_t>(dense_->d) * sizeof(float);
    const auto* graph = dynamic_cast<const faiss::IndexHNSW*>(dense_.get());
    return rows + (graph != nullptr ? linkBytes(graph->hnsw) : 0);
  }

  std::size_t size() const {
    if (hamming_) return hamming_->size();
    return static_cast<std::size_t>(binary_ ? binary_->ntotal : dense_->ntotal);
  }

  /// The k nearest rows of each query row (row-major, n x k): distance and row label (-1: none).
  void search(const cv::Mat& rows, int k, std::vector<double>& distances,
              std::vector<Label>& labels) const {
    const std::size_t n = static_cast<std::size_t>(rows.rows) * static_cast<std::size_t>(k);
    labels.assign(n, -1);
    distances.assign(n, 0.0);
    useOneThread();
    if (hamming_) {
      hamming_->search(rows, k, distances, labels);
    } else if (binary_) {
      std::vector<std::int32_t> bits(n);
      binary_->search(rows.rows, rows.ptr<std::uint8_t>(0), k, bits.data(), labels.data());
      std::copy(bits.begin(), bits.end(), distances.begin());
    } else {
      std::vector<float> similarities(n);
      dense_->search(rows.rows, rows.ptr<float>(0), k, similarities.data(), labels.data());
      for (std::size_t j = 0; j < n; ++j)
        distances[j] = 1.0 - static_cast<double>(similarities[j]);
    }
  }

  /// Rows `labels` as stored.
  cv::Mat rows(const std::vector<Label>& labels, int type, int cols) const {
    cv::Mat out(static_cast<int>(labels.size()), cols, type);
    for (std::size_t i = 0; i < labels.size(); ++i) {
      if (hamming_) {
        hamming_->row(labels[i], out.ptr<std::uint8_t>(static_cast<int>(i)));
      } else if (binary_) {
        binary_->reconstruct(labels[i], out.ptr<std::uint8_t>(static_cast<int>(i)));
      } else {
        dense_->reconstruct(labels[i], out.ptr<float>(static_cast<int>(i)));
      }
    }
    return out;
  }

 private:
  static std::size_t linkBytes(const faiss::HNSW& hnsw) {
    return hnsw.neighbors.size() * sizeof(faiss::HNSW::storage_idx_t) +
           hnsw.levels.size() * sizeof(int) + hnsw.offsets.size() * sizeof(std::size_t);
  }

  static std::unique_ptr<faiss::IndexBinary> binaryGraph(int bits, int hnsw_search) {
    auto index = std::make_unique<faiss::IndexBinaryHNSW>(bits, kHnswLinks);
    index->hnsw.efConstruction = kHnswConstruction;
    index->hnsw.efSearch = hnsw_search;
    return index;
  }

  static std::unique_ptr<faiss::Index> denseIndex(int dims, int hnsw_search) {
    if (hnsw_search == 0) return std::make_unique<faiss::IndexFlatIP>(dims);
    auto index =
        std::make_unique<faiss::IndexHNSWFlat>(dims, kHnswLinks, faiss::METRIC_INNER_PRODUCT);
    index->hnsw.efConstruction = kHnswConstruction;
    index->hnsw.efSearch = hnsw_search;
    return index;
  }

  std::unique_ptr<HammingRows> hamming_;
  std::unique_ptr<faiss::IndexBinary> binary_;
  std::unique_ptr<faiss::Index> dense_;
};

KeyFrameDatabase::KeyFrameDatabase(const KeyFrameDatabaseOptions& options) : options_(options) {
  options_.validate();
}

KeyFrameDatabase::~KeyFrameDatabase() = default;

void KeyFrameDatabase::createIndexes(const cv::Mat& rows) {
  type_ = rows.type();
  cols_ = rows.cols;
  graph_ = std::make_unique<RowIndex>(type_, cols_, options_.hnsw_search);
  held_index_ = std::make_unique<RowIndex>(type_, cols_, 0);
}

void KeyFrameDatabase::add(map::KeyFrameId id, TimeNs t_ns, const cv::Mat& rows) {
  if (rows.empty()) return;
  if (rows.type() != CV_8UC1 && rows.type() != CV_32FC1) {
    throw std::invalid_argument("KeyFrameDatabase: descriptors must be CV_8UC1 or CV_32FC1");
  }
  if (type_ < 0) createIndexes(rows);
  if (rows.type() != type_ || rows.cols != cols_) {
    throw std::invalid_argument("KeyFrameDatabase: keyframe " + std::to_string(id) +
                                " has descriptors of another type or length than the index");
  }
  Held held{id, t_ns, rows.type() == CV_32FC1 ? normalizedRows(rows) : rows.clone()};
  held_index_->add(held.rows);
  held_owners_.insert(held_owners_.end(), static_cast<std::size_t>(rows.rows), id);
  const auto later = std::upper_bound(held_.begin(), held_.end(), t_ns,
                                      [](TimeNs t, const Held& h) { return t < h.t_ns; });
  held_.insert(later, std::move(held));
}

void KeyFrameDatabase::settle(TimeNs now_ns, const std::vector<map::KeyFrameId>& alive) {
  if (type_ < 0) return;
  const auto is_alive = [&](map::KeyFrameId id) {
    return std::binary_search(alive.begin(), alive.end(), id);
  };
  const TimeNs settled = now_ns - secondsToNs(options_.hold_s);
  std::vector<Held> still_held;
  for (Held& held : held_) {
    if (!is_alive(held.id)) continue;
    if (held.t_ns > settled) {
      still_held.push_back(std::move(held));
      continue;
    }
    graph_->add(held.rows);
    graph_owners_.insert(graph_owners_.end(), static_cast<std::size_t>(held.rows.rows), held.id);
    graph_rows_of_[held.id] = held.rows.rows;
  }
  const bool held_changed = still_held.size() != held_.size();
  held_ = std::move(still_held);
  if (held_changed) rebuildHeldIndex();
  for (auto it = graph_rows_of_.begin(); it != graph_rows_of_.end();) {
    if (is_alive(it->first)) {
      ++it;
      continue;
    }
    culled_graph_rows_ += static_cast<std::size_t>(it->second);
    it = graph_rows_of_.erase(it);
  }
  if (static_cast<double>(culled_graph_rows_) >
      options_.max_culled_share * static_cast<double>(graph_owners_.size())) {
    rebuildGraph();
  }
}

void KeyFrameDatabase::rebuildHeldIndex() {
  held_index_ = std::make_unique<RowIndex>(type_, cols_, 0);
  held_owners_.clear();
  for (const Held& held : held_) {
    held_index_->add(held.rows);
    held_owners_.insert(held_owners_.end(), static_cast<std::size_t>(held.rows.rows), held.id);
  }
}

void KeyFrameDatabase::rebuildGraph() {
  std::vector<Label> kept;
  std::vector<map::KeyFrameId> owners;
  for (std::size_t r = 0; r < graph_owners_.size(); ++r) {
    if (!graph_rows_of_.contains(graph_owners_[r])) continue;
    kept.push_back(static_cast<Label>(r));
    owners.push_back(graph_owners_[r]);
  }
  const cv::Mat rows = graph_->rows(kept, type_, cols_);
  // The old graph goes first: the peak is the new graph plus the living rows, not two graphs.
  graph_ = std::make_unique<RowIndex>(type_, cols_, options_.hnsw_search);
  if (!rows.empty()) graph_->add(rows);
  graph_owners_ = std::move(owners);
  culled_graph_rows_ = 0;
  ++rebuilds_;
}

bool KeyFrameDatabase::nearEnough(double distance) const {
  if (type_ == CV_8UC1) return distance <= options_.max_hamming;
  return 1.0 - distance >= options_.min_similarity;
}

std::vector<std::vector<map::KeyFrameId>> KeyFrameDatabase::neighbourOwners(
    const cv::Mat& rows) const {
  const int n = rows.rows;
  const int k = options_.neighbours;
  // Candidates of each query row from both indexes, nearest first; graph rows of culled
  // keyframes do not vote.
  std::vector<std::vector<Neighbour>> nearest(static_cast<std::size_t>(n));
  const auto collect = [&](const RowIndex& index, const std::vector<map::KeyFrameId>& owners,
                           bool check_alive) {
    if (index.size() == 0) return;
    const int kk = std::min<int>(k, static_cast<int>(index.size()));
    std::vector<double> distances;
    std::vector<Label> labels;
    index.search(rows, kk, distances, labels);
    for (std::size_t j = 0; j < labels.size(); ++j) {
      if (labels[j] < 0 || !nearEnough(distances[j])) continue;
      const map::KeyFrameId owner = owners[static_cast<std::size_t>(labels[j])];
      if (check_alive && !graph_rows_of_.contains(owner)) continue;
      nearest[j / static_cast<std::size_t>(kk)].push_back({distances[j], owner});
    }
  };
  collect(*graph_, graph_owners_, true);
  collect(*held_index_, held_owners_, false);
  std::vector<std::vector<map::KeyFrameId>> out(static_cast<std::size_t>(n));
  for (std::size_t q = 0; q < nearest.size(); ++q) {
    std::vector<Neighbour>& candidates = nearest[q];
    std::stable_sort(
        candidates.begin(), candidates.end(),
        [](const Neighbour& a, const Neighbour& b) { return a.distance < b.distance; });
    if (static_cast<int>(candidates.size()) > k) candidates.resize(static_cast<std::size_t>(k));
    for (const Neighbour& c : candidates)
      if (std::find(out[q].begin(), out[q].end(), c.owner) == out[q].end())
        out[q].push_back(c.owner);
  }
  return out;
}

std::vector<PlaceScore> KeyFrameDatabase::query(const cv::Mat& rows) const {
  if (rows.empty() || numKeyFrames() == 0) return {};
  if (rows.type() != type_ || rows.cols != cols_) {
    throw std::invalid_argument("KeyFrameDatabase: query descriptors of another type or length");
  }
  const cv::Mat data = rows.type() == CV_32FC1 ? normalizedRows(rows)
                       : rows.isContinuous()   ? rows
                                               : rows.clone();
  std::map<map::KeyFrameId, int> votes;
  for (const std::vector<map::KeyFrameId>& owners : neighbourOwners(data))
    for (const map::KeyFrameId owner : owners)
      ++votes[owner];
  std::vector<PlaceScore> scores;
  scores.reserve(votes.size());
  for (const auto& [id, count] : votes)
    scores.push_back({id, count, static_cast<double>(count) / rows.rows});
  std::stable_sort(scores.begin(), scores.end(),
                   [](const PlaceScore& a, const PlaceScore& b) { return a.votes > b.votes; });
  return scores;
}

std::size_t KeyFrameDatabase::numDescriptors() const {
  return graph_owners_.size() + held_owners_.size();
}

std::size_t KeyFrameDatabase::indexBytes() const {
  return (graph_ ? graph_->bytes() : 0) + (held_index_ ? held_index_->bytes() : 0);
}

void KeyFrameDatabase::clear() {
  type_ = -1;
  cols_ = 0;
  graph_.reset();
  held_index_.reset();
  graph_owners_.clear();
  graph_rows_of_.clear();
  culled_graph_rows_ = 0;
  held_.clear();
  held_owners_.clear();
}

}  // namespace superdyna::loop

#include "superdyna/loop/keyframe_database.h"

#include <faiss/IndexBinaryFlat.h>
#include <faiss/IndexBinaryHNSW.h>
#include <faiss/IndexFlat.h>
#include <faiss/IndexHNSW.h>
#include <omp.h>

#include <algorithm>
#include <cstdint>
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

/// One faiss index, binary or float, created by the first keyframe.
struct KeyFrameDatabase::Index {
  int type = -1;  ///< CV_8UC1 or CV_32FC1.
  int cols = 0;
  std::unique_ptr<faiss::IndexBinary> binary;
  std::unique_ptr<faiss::Index> dense;
};

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

std::unique_ptr<faiss::IndexBinary> binaryIndex(int bits, int hnsw_search) {
  if (hnsw_search == 0) return std::make_unique<faiss::IndexBinaryFlat>(bits);
  auto index = std::make_unique<faiss::IndexBinaryHNSW>(bits, kHnswLinks);
  index->hnsw.efConstruction = kHnswConstruction;
  index->hnsw.efSearch = hnsw_search;
  return index;
}

std::unique_ptr<faiss::Index> denseIndex(int dims, int hnsw_search) {
  if (hnsw_search == 0) return std::make_unique<faiss::IndexFlatIP>(dims);
  auto index =
      std::make_unique<faiss::IndexHNSWFlat>(dims, kHnswLinks, faiss::METRIC_INNER_PRODUCT);
  index->hnsw.efConstruction = kHnswConstruction;
  index->hnsw.efSearch = hnsw_search;
  return index;
}

/// faiss in the calling thread only: deterministic and no oversubscription of the pipeline's cores.
void useOneThread() {
  omp_set_num_threads(1);
}

}  // namespace

KeyFrameDatabase::KeyFrameDatabase(const KeyFrameDatabaseOptions& options)
    : options_(options), index_(std::make_unique<Index>()) {
  options_.validate();
}

KeyFrameDatabase::~KeyFrameDatabase() = default;

void KeyFrameDatabase::add(map::KeyFrameId id, const cv::Mat& rows) {
  if (rows.empty()) return;
  if (rows.type() != CV_8UC1 && rows.type() != CV_32FC1) {
    throw std::invalid_argument("KeyFrameDatabase: descriptors must be CV_8UC1 or CV_32FC1");
  }
  Index& index = *index_;
  if (index.type < 0) {
    index.type = rows.type();
    index.cols = rows.cols;
    if (rows.type() == CV_8UC1) {
      index.binary = binaryIndex(8 * rows.cols, options_.hnsw_search);
    } else {
      index.dense = denseIndex(rows.cols, options_.hnsw_search);
    }
  }
  if (rows.type() != index.type || rows.cols != index.cols) {
    throw std::invalid_argument("KeyFrameDatabase: keyframe " + std::to_string(id) +
                                " has descriptors of another type or length than the index");
  }
  useOneThread();
  const cv::Mat data = rows.isContinuous() ? rows : rows.clone();
  if (index.binary) {
    index.binary->add(data.rows, data.ptr<std::uint8_t>(0));
  } else {
    const cv::Mat unit = normalizedRows(data);
    index.dense->add(unit.rows, unit.ptr<float>(0));
  }
  owners_.insert(owners_.end(), static_cast<std::size_t>(rows.rows), id);
  ++keyframes_;
}

std::vector<std::vector<map::KeyFrameId>> KeyFrameDatabase::neighbourOwners(
    const cv::Mat& rows) const {
  const Index& index = *index_;
  const int n = rows.rows;
  const int k = std::min<int>(options_.neighbours, static_cast<int>(owners_.size()));
  std::vector<faiss::Index::idx_t> labels(static_cast<std::size_t>(n) * k, -1);
  std::vector<std::vector<map::KeyFrameId>> out(static_cast<std::size_t>(n));
  useOneThread();
  const cv::Mat data = rows.isContinuous() ? rows : rows.clone();
  if (index.binary) {
    std::vector<std::int32_t> distances(labels.size());
    index.binary->search(n, data.ptr<std::uint8_t>(0), k, distances.data(), labels.data());
    for (std::size_t j = 0; j < labels.size(); ++j)
      if (distances[j] > options_.max_hamming) labels[j] = -1;
  } else {
    std::vector<float> similarities(labels.size());
    const cv::Mat unit = normalizedRows(data);
    index.dense->search(n, unit.ptr<float>(0), k, similarities.data(), labels.data());
    for (std::size_t j = 0; j < labels.size(); ++j)
      if (similarities[j] < options_.min_similarity) labels[j] = -1;
  }
  for (int q = 0; q < n; ++q) {
    std::vector<map::KeyFrameId>& owners = out[static_cast<std::size_t>(q)];
    for (int j = 0; j < k; ++j) {
      const faiss::Index::idx_t label = labels[static_cast<std::size_t>(q) * k + j];
      if (label < 0) continue;
      const map::KeyFrameId owner = owners_[static_cast<std::size_t>(label)];
      if (std::find(owners.begin(), owners.end(), owner) == owners.end()) owners.push_back(owner);
    }
  }
  return out;
}

std::vector<PlaceScore> KeyFrameDatabase::query(const cv::Mat& rows) const {
  if (rows.empty() || owners_.empty()) return {};
  if (rows.type() != index_->type || rows.cols != index_->cols) {
    throw std::invalid_argument("KeyFrameDatabase: query descriptors of another type or length");
  }
  std::map<map::KeyFrameId, int> votes;
  for (const std::vector<map::KeyFrameId>& owners : neighbourOwners(rows))
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

std::size_t KeyFrameDatabase::descriptorBytes() const {
  const std::size_t row_bytes = index_->type == CV_32FC1
                                    ? sizeof(float) * static_cast<std::size_t>(index_->cols)
                                    : static_cast<std::size_t>(index_->cols);
  return owners_.size() * row_bytes;
}

void KeyFrameDatabase::clear() {
  index_ = std::make_unique<Index>();
  owners_.clear();
  keyframes_ = 0;
}

}  // namespace superdyna::loop

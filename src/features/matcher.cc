#include "superdyna/features/matcher.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include "superdyna/core/error.h"

namespace superdyna::features {

namespace {

constexpr double kNoDistance = std::numeric_limits<double>::infinity();

/// Best and second-best distance over distinct candidates.
struct BestTwo {
  double best = kNoDistance;
  double second = kNoDistance;
  int index = -1;

  /// Ties go to the lower index, so the result does not depend on the order of the offers.
  void offer(double distance, int candidate) {
    if (distance < best || (distance == best && candidate < index)) {
      second = best;
      best = distance;
      index = candidate;
    } else if (distance < second) {
      second = distance;
    }
  }
  /// Passes the distance bound and best < ratio * second (always when ratio >= 1 or alone).
  bool accepted(double max_distance, double ratio) const {
    if (index < 0 || best > max_distance) return false;
    if (ratio >= 1.0 || second == kNoDistance) return true;
    return best < ratio * second;
  }
};

/// Keeps, for every train index, only the match with the smallest distance (ties: the earlier
/// match); result ordered by query.
std::vector<Match> uniqueTrain(const std::vector<Match>& matches, std::size_t train_count) {
  std::vector<int> owner(train_count, -1);
  for (std::size_t k = 0; k < matches.size(); ++k) {
    int& slot = owner[static_cast<std::size_t>(matches[k].train)];
    if (slot < 0 || matches[k].distance < matches[static_cast<std::size_t>(slot)].distance) {
      slot = static_cast<int>(k);
    }
  }
  std::vector<Match> kept;
  for (std::size_t k = 0; k < matches.size(); ++k) {
    if (owner[static_cast<std::size_t>(matches[k].train)] == static_cast<int>(k)) {
      kept.push_back(matches[k]);
    }
  }
  return kept;
}

void requireRatio(double ratio) {
  if (!(ratio > 0.0 && ratio <= 1.0)) {
    throw OptionError("ratio", fmt::format("must be in (0, 1], got {}", ratio));
  }
}

}  // namespace

// The hardware population count where the CPU has one (chosen once at load time): without it
// every 64-bit word costs a call into libgcc, 12 % of the moving-object test. Not in
// ThreadSanitizer builds: the clone's resolver runs while the dynamic loader relocates, before the
// sanitizer's runtime is up, and its instrumented entry crashes every binary at start.
#if defined(__x86_64__) && defined(__has_attribute) && !defined(__SANITIZE_THREAD__)
#if __has_attribute(target_clones)
__attribute__((target_clones("popcnt", "default")))
#endif
#endif
int hammingDistance(const std::uint8_t* a, const std::uint8_t* b, int bytes) {
  int distance = 0;
  int i = 0;
  for (; i + 8 <= bytes; i += 8) {
    std::uint64_t wa, wb;
    std::memcpy(&wa, a + i, sizeof wa);
    std::memcpy(&wb, b + i, sizeof wb);
    distance += std::popcount(wa ^ wb);
  }
  for (; i < bytes; ++i)
    distance += std::popcount(static_cast<unsigned>(a[i] ^ b[i]));
  return distance;
}

float l2Distance(const float* a, const float* b, int length) {
  float sum = 0.0f;
  for (int k = 0; k < length; ++k) {
    const float d = a[k] - b[k];
    sum += d * d;
  }
  return std::sqrt(sum);
}

DescriptorMetric::DescriptorMetric(const FeatureSet& query, const FeatureSet& train,
                                   const char* who)
    : query_(&query.descriptors),
      train_(&train.descriptors),
      type_(query.descriptor_type),
      length_(query.descriptorLength()) {
  query.validate();
  train.validate();
  if (query.descriptor_type != train.descriptor_type) {
    throw InputError(fmt::format("{}: descriptor types differ ({} and {})", who,
                                 toString(query.descriptor_type), toString(train.descriptor_type)));
  }
  if (!query.empty() && !train.empty() && query.descriptorLength() != train.descriptorLength()) {
    throw InputError(fmt::format("{}: descriptor lengths differ ({} and {})", who,
                                 query.descriptorLength(), train.descriptorLength()));
  }
}

double descriptorDistance(const cv::Mat& a, const cv::Mat& b) {
  if (a.rows != 1 || b.rows != 1 || a.cols != b.cols || a.type() != b.type() ||
      (a.type() != CV_8UC1 && a.type() != CV_32FC1)) {
    throw InputError(
        "descriptorDistance: expected two CV_8UC1 or two CV_32FC1 rows of equal length");
  }
  if (a.type() == CV_8UC1)
    return hammingDistance(a.ptr<std::uint8_t>(0), b.ptr<std::uint8_t>(0), a.cols);
  return l2Distance(a.ptr<float>(0), b.ptr<float>(0), a.cols);
}

bool hasOrientation(const FeatureSet& features) {
  return !features.empty() && std::all_of(features.keypoints.begin(), features.keypoints.end(),
                                          [](const Keypoint& k) { return k.angle >= 0.0f; });
}

int hammingDistance(const cv::Mat& a, const cv::Mat& b) {
  if (a.type() != CV_8UC1 || b.type() != CV_8UC1 || a.rows != 1 || b.rows != 1 ||
      a.cols != b.cols) {
    throw InputError("hammingDistance: expected two CV_8UC1 rows of equal length");
  }
  return hammingDistance(a.ptr<std::uint8_t>(0), b.ptr<std::uint8_t>(0), a.cols);
}

void OrientationCheckOptions::validate() const {
  if (bins < 1 || bins > 360) throw OptionError("bins", fmt::format("must be in [1, 360]"));
  if (keep_bins < 1 || keep_bins > bins) throw OptionError("keep_bins", "must be in [1, bins]");
  if (!(min_bin_fraction >= 0.0 && min_bin_fraction <= 1.0)) {
    throw OptionError("min_bin_fraction", "must be in [0, 1]");
  }
}

std::vector<Match> filterByOrientation(const std::vector<Match>& matches,
                                       const std::vector<Keypoint>& query,
                                       const std::vector<Keypoint>& train,
                                       const OrientationCheckOptions& options) {
  options.validate();
  const double bin_width = 360.0 / options.bins;
  std::vector<int> bin_of(matches.size(), -1);
  std::vector<int> counts(static_cast<std::size_t>(options.bins), 0);
  for (std::size_t k = 0; k < matches.size(); ++k) {
    const float a = query.at(static_cast<std::size_t>(matches[k].query)).angle;
    const float b = train.at(static_cast<std::size_t>(matches[k].train)).angle;
    if (a < 0.0f || b < 0.0f) continue;
    double difference = std::fmod(static_cast<double>(a) - b, 360.0);
    if (difference < 0.0) difference += 360.0;
    const int bin = static_cast<int>(std::floor(difference / bin_width + 0.5)) % options.bins;
    bin_of[k] = bin;
    ++counts[static_cast<std::size_t>(bin)];
  }
  std::vector<int> order(counts.size());
  for (std::size_t b = 0; b < order.size(); ++b)
    order[b] = static_cast<int>(b);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return counts[static_cast<std::size_t>(a)] > counts[static_cast<std::size_t>(b)];
  });
  std::vector<bool> keep(counts.size(), false);
  const int top = counts[static_cast<std::size_t>(order.front())];
  for (int k = 0; k < options.keep_bins; ++k) {
    const int count = counts[static_cast<std::size_t>(order[static_cast<std::size_t>(k)])];
    if (count > 0 && (k == 0 || count >= options.min_bin_fraction * top)) {
      keep[static_cast<std::size_t>(order[static_cast<std::size_t>(k)])] = true;
    }
  }
  std::vector<Match> kept;
  for (std::size_t k = 0; k < matches.size(); ++k) {
    if (bin_of[k] >= 0 && keep[static_cast<std::size_t>(bin_of[k])]) kept.push_back(matches[k]);
  }
  return kept;
}

void BruteForceMatchOptions::validate() const {
  if (max_distance < 0) throw OptionError("max_distance", "must be >= 0");
  if (!(max_l2_distance >= 0.0)) throw OptionError("max_l2_distance", "must be >= 0");
  requireRatio(ratio);
  orientation.validate();
}

std::vector<Match> matchBruteForce(const FeatureSet& query, const FeatureSet& train,
                                   const BruteForceMatchOptions& options) {
  options.validate();
  const DescriptorMetric distance(query, train, "matchBruteForce");
  if (query.empty() || train.empty()) return {};
  const double max_distance = distance.bound(options.max_distance, options.max_l2_distance);
  const int n = static_cast<int>(query.size()), m = static_cast<int>(train.size());
  std::vector<BestTwo> rows(static_cast<std::size_t>(n));
  std::vector<BestTwo> cols(static_cast<std::size_t>(m));
  for (int i = 0; i < n; ++i) {
    const int class_id = query.keypoints[static_cast<std::size_t>(i)].class_id;
    for (int j = 0; j < m; ++j) {
      if (options.same_class_only &&
          train.keypoints[static_cast<std::size_t>(j)].class_id != class_id) {
        continue;
      }
      const double d = distance(i, j);
      rows[static_cast<std::size_t>(i)].offer(d, j);
      cols[static_cast<std::size_t>(j)].offer(d, i);
    }
  }
  std::vector<Match> matches;
  for (int i = 0; i < n; ++i) {
    const BestTwo& row = rows[static_cast<std::size_t>(i)];
    if (!row.accepted(max_distance, options.ratio)) continue;
    if (options.mutual && cols[static_cast<std::size_t>(row.index)].index != i) continue;
    matches.push_back({i, row.index, row.best});
  }
  if (!options.mutual) matches = uniqueTrain(matches, train.size());
  if (options.check_orientation && hasOrientation(query) && hasOrientation(train)) {
    matches = filterByOrientation(matches, query.keypoints, train.keypoints, options.orientation);
  }
  return matches;
}

KeypointGrid::KeypointGrid(const std::vector<Keypoint>& keypoints, cv::Size image_size,
                           int cell_size_px)
    : KeypointGrid(keypoints, image_size, cell_size_px, std::vector<char>(keypoints.size(), 1)) {}

KeypointGrid::KeypointGrid(const std::vector<Keypoint>& keypoints, cv::Size image_size,
                           int cell_size_px, const std::vector<char>& include)
    : cell_size_(cell_size_px) {
  if (cell_size_px <= 0) throw OptionError("cell_size_px", "must be > 0");
  if (include.size() != keypoints.size()) {
    throw InputError(fmt::format("KeypointGrid: {} include flags for {} keypoints", include.size(),
                                 keypoints.size()));
  }
  cols_ = std::max(1, (image_size.width + cell_size_ - 1) / cell_size_);
  rows_ = std::max(1, (image_size.height + cell_size_ - 1) / cell_size_);
  cells_.resize(static_cast<std::size_t>(cols_ * rows_));
  pixels_.reserve(keypoints.size());
  octaves_.reserve(keypoints.size());
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    const Eigen::Vector2d& p = keypoints[i].pixel;
    pixels_.push_back(p);
    octaves_.push_back(keypoints[i].octave);
    if (!include[i]) continue;
    const int c = std::clamp(static_cast<int>(std::floor(p.x() / cell_size_)), 0, cols_ - 1);
    const int r = std::clamp(static_cast<int>(std::floor(p.y() / cell_size_)), 0, rows_ - 1);
    cells_[static_cast<std::size_t>(r * cols_ + c)].push_back(static_cast<int>(i));
  }
}

std::vector<int> KeypointGrid::within(const Eigen::Vector2d& center, double radius_px,
                                      int min_octave, int max_octave) const {
  std::vector<int> found;
  forEachWithin(center, radius_px, min_octave, max_octave, [&](int i) { found.push_back(i); });
  std::sort(found.begin(), found.end());
  return found;
}

void ProjectionMatchOptions::validate() const {
  if (!(radius_px > 0.0)) throw OptionError("radius_px", "must be > 0");
  if (max_distance < 0) throw OptionError("max_distance", "must be >= 0");
  if (!(max_l2_distance >= 0.0)) throw OptionError("max_l2_distance", "must be >= 0");
  requireRatio(ratio);
  if (min_octave_offset < -kMaxOctaveOffset || max_octave_offset > kMaxOctaveOffset) {
    throw OptionError(
        min_octave_offset < -kMaxOctaveOffset ? "min_octave_offset" : "max_octave_offset",
        "must lie in [-100, 100]");
  }
  if (min_octave_offset > max_octave_offset) {
    throw OptionError("min_octave_offset", "must be <= max_octave_offset");
  }
  if (!(radius_octave_scale >= 1.0) || !std::isfinite(radius_octave_scale)) {
    throw OptionError("radius_octave_scale", "must be a finite number >= 1");
  }
  orientation.validate();
}

namespace {

/// Sets best.second to the closest offer other than the best at the best's octave.
void keepSecondAtBestOctave(BestTwo& best, const std::vector<std::pair<double, int>>& offers,
                            const std::vector<Keypoint>& train) {
  if (best.index < 0) return;
  const int octave = train[static_cast<std::size_t>(best.index)].octave;
  best.second = kNoDistance;
  for (const auto& [d, j] : offers) {
    if (j != best.index && train[static_cast<std::size_t>(j)].octave == octave) {
      best.second = std::min(best.second, d);
    }
  }
}

}  // namespace

std::vector<Match> matchByProjection(const FeatureSet& query,
                                     const std::vector<Eigen::Vector2d>& predicted,
                                     const FeatureSet& train, const KeypointGrid& train_grid,
                                     const ProjectionMatchOptions& options) {
  options.validate();
  const DescriptorMetric distance(query, train, "matchByProjection");
  if (predicted.size() != query.size()) {
    throw InputError(fmt::format("matchByProjection: {} predicted pixels for {} query features",
                                 predicted.size(), query.size()));
  }
  if (train_grid.size() != train.size()) {
    throw InputError(
        fmt::format("matchByProjection: the grid indexes {} keypoints, not the {} "
                    "train features",
                    train_grid.size(), train.size()));
  }
  const double max_distance = distance.bound(options.max_distance, options.max_l2_distance);
  std::vector<Match> matches;
  std::vector<std::pair<double, int>> offers;  // (distance, train index) for ratio_within_octave
  for (std::size_t i = 0; i < query.size(); ++i) {
    if (!predicted[i].allFinite()) continue;
    const int octave = query.keypoints[i].octave;
    const int min_octave = octave + options.min_octave_offset;
    const int max_octave = octave + options.max_octave_offset;
    const double radius = options.radius_px * std::pow(options.radius_octave_scale, octave);
    const int class_id = query.keypoints[i].class_id;
    BestTwo best;
    offers.clear();
    train_grid.forEachWithin(predicted[i], radius, min_octave, max_octave, [&](int j) {
      if (options.same_class_only &&
          train.keypoints[static_cast<std::size_t>(j)].class_id != class_id) {
        return;
      }
      const double d = distance(static_cast<int>(i), j);
      best.offer(d, j);
      if (options.ratio_within_octave) offers.emplace_back(d, j);
    });
    if (options.ratio_within_octave) keepSecondAtBestOctave(best, offers, train.keypoints);
    if (best.accepted(max_distance, options.ratio)) {
      matches.push_back({static_cast<int>(i), best.index, best.best});
    }
  }
  matches = uniqueTrain(matches, train.size());
  if (options.check_orientation && hasOrientation(query) && hasOrientation(train)) {
    matches = filterByOrientation(matches, query.keypoints, train.keypoints, options.orientation);
  }
  return matches;
}

}  // namespace superdyna::features

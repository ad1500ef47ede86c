#include "superdyna/map/map.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "superdyna/core/error.h"

namespace superdyna::map {

namespace {

/// Covisible keyframes of one row, by decreasing weight then increasing id.
std::vector<CovisibleKeyFrame> sortedByWeight(const std::map<KeyFrameId, int>& row,
                                              int min_weight) {
  std::vector<CovisibleKeyFrame> out;
  for (const auto& [other, weight] : row) {
    if (weight >= min_weight) out.push_back({other, weight});
  }
  std::stable_sort(
      out.begin(), out.end(),
      [](const CovisibleKeyFrame& a, const CovisibleKeyFrame& b) { return a.weight > b.weight; });
  return out;
}

template <typename Container>
std::vector<typename Container::key_type> sortedKeys(const Container& container) {
  std::vector<typename Container::key_type> keys;
  keys.reserve(container.size());
  for (const auto& entry : container)
    keys.push_back(entry.first);
  std::sort(keys.begin(), keys.end());
  return keys;
}

std::string describePair(MapPointId point_id, KeyFrameId keyframe_id) {
  return "point " + std::to_string(point_id) + " / keyframe " + std::to_string(keyframe_id);
}

}  // namespace

int KeyFrame::numTrackedPoints() const {
  return static_cast<int>(
      std::count_if(map_points.begin(), map_points.end(),
                    [](MapPointId point_id) { return point_id != kNoMapPoint; }));
}

void MapOptions::validate() const {
  if (T_b_c.empty()) throw OptionError("map.T_b_c", "needs at least one camera");
  if (num_levels < 1) throw OptionError("map.num_levels", "must be >= 1");
  // A single level (learned extractors) has no scale between levels: 1 is then fine.
  if (!(scale_factor >= 1.0) || !std::isfinite(scale_factor) ||
      (num_levels > 1 && !(scale_factor > 1.0))) {
    throw OptionError("map.scale_factor",
                      "must be a finite number > 1 (>= 1 with a single pyramid level)");
  }
  if (max_imu_samples_per_link < 16) {
    throw OptionError("map.max_imu_samples_per_link", "must be >= 16");
  }
}

Map::Map(MapOptions options) : options_(std::move(options)) {
  options_.validate();
}

Map::Map(MapOptions options, KeyFrameId first_keyframe_id, MapPointId first_point_id)
    : Map(std::move(options)) {
  if (first_keyframe_id < 0 || first_point_id < 0)
    throw std::invalid_argument("Map: first ids must be >= 0");
  next_keyframe_id_ = first_keyframe_id;
  next_point_id_ = first_point_id;
}

void Map::absorb(Map& other) {
  if (&other == this) throw std::invalid_argument("Map::absorb: a map cannot absorb itself");
  const std::scoped_lock lock(mutex_, other.mutex_);
  if (other.options_.T_b_c.size() != options_.T_b_c.size() ||
      other.options_.scale_factor != options_.scale_factor ||
      other.options_.num_levels != options_.num_levels) {
    throw std::invalid_argument("Map::absorb: the maps have other rigs or pyramids");
  }
  for (const auto& [id, keyframe] : other.keyframes_)
    if (keyframes_.contains(id) || erased_.contains(id))
      throw std::invalid_argument("Map::absorb: both maps have keyframe " + std::to_string(id));
  for (const auto& [id, erased] : other.erased_)
    if (keyframes_.contains(id) || erased_.contains(id))
      throw std::invalid_argument("Map::absorb: both maps had keyframe " + std::to_string(id));
  for (const auto& [id, point] : other.points_)
    if (points_.contains(id))
      throw std::invalid_argument("Map::absorb: both maps have map point " + std::to_string(id));
  keyframes_.merge(other.keyframes_);
  points_.merge(other.points_);
  covisibility_.merge(other.covisibility_);
  erased_.merge(other.erased_);
  next_keyframe_id_ = std::max(next_keyframe_id_, other.next_keyframe_id_);
  next_point_id_ = std::max(next_point_id_, other.next_point_id_);
  newest_keyframe_ = std::max(newest_keyframe_, other.newest_keyframe_);
  other.keyframes_.clear();
  other.points_.clear();
  other.covisibility_.clear();
  other.erased_.clear();
  other.corrections_.clear();
  other.newest_keyframe_ = kNoKeyFrame;
}

// ---- Private helpers (called with the mutex held)
// ------------------------------------------------

MapPoint* Map::findPoint(MapPointId id) {
  const auto it = points_.find(id);
  return it == points_.end() ? nullptr : &it->second;
}

KeyFrame* Map::findKeyFrame(KeyFrameId id) {
  const auto it = keyframes_.find(id);
  return it == keyframes_.end() ? nullptr : &it->second;
}

void Map::validateKeyFrame(const KeyFrame& keyframe) const {
  const std::size_t n = keyframe.keypoints.size();
  if (!keyframe.descriptors.empty() && static_cast<std::size_t>(keyframe.descriptors.rows) != n) {
    throw std::invalid_argument("Map::addKeyFrame: " + std::to_string(keyframe.descriptors.rows) +
                                " descriptor rows for " + std::to_string(n) + " keypoints");
  }
  if (!keyframe.map_points.empty() && keyframe.map_points.size() != n) {
    throw std::invalid_argument("Map::addKeyFrame: " + std::to_string(keyframe.map_points.size()) +
                                " map point slots for " + std::to_string(n) + " keypoints");
  }
  const int num_cameras = static_cast<int>(options_.T_b_c.size());
  for (const KeyFrameKeypoint& keypoint : keyframe.keypoints) {
    if (keypoint.camera < 0 || keypoint.camera >= num_cameras) {
      throw std::invalid_argument("Map::addKeyFrame: keypoint camera " +
                                  std::to_string(keypoint.camera) + " outside the " +
                                  std::to_string(num_cameras) + " cameras of the rig");
    }
  }
}

void Map::addCovisibility(KeyFrameId a, KeyFrameId b, int delta) {
  for (const auto& [from, to] : {std::pair{a, b}, std::pair{b, a}}) {
    CovisibilityRow& row = covisibility_[from];
    const int weight = (row[to] += delta);
    if (weight <= 0) row.erase(to);
  }
}

void Map::attachObservation(MapPoint& point, KeyFrame& keyframe, int keypoint_index) {
  for (const auto& observation : point.observations) {
    addCovisibility(keyframe.id, observation.first, +1);
  }
  point.observations[keyframe.id] = keypoint_index;
  keyframe.map_points[static_cast<std::size_t>(keypoint_index)] = point.id;
}

void Map::detachObservation(MapPoint& point, KeyFrame& keyframe) {
  const auto it = point.observations.find(keyframe.id);
  keyframe.map_points[static_cast<std::size_t>(it->second)] = kNoMapPoint;
  point.observations.erase(it);
  for (const auto& observation : point.observations) {
    addCovisibility(keyframe.id, observation.first, -1);
  }
}

void Map::detachAllObservations(MapPoint& point) {
  while (!point.observations.empty()) {
    detachObservation(point, keyframes_.at(point.observations.begin()->first));
  }
}

// ---- Structure ---------------------------------------------------------------------------------

KeyFrameId Map::addKeyFrame(KeyFrame keyframe) {
  validateKeyFrame(keyframe);
  const std::lock_guard lock(mutex_);
  std::vector<MapPointId> requested = std::move(keyframe.map_points);
  keyframe.map_points.assign(keyframe.keypoints.size(), kNoMapPoint);
  keyframe.id = next_keyframe_id_++;
  keyframe.previous = newest_keyframe_;
  newest_keyframe_ = keyframe.id;
  covisibility_[keyframe.id];
  KeyFrame& stored = keyframes_.emplace(keyframe.id, std::move(keyframe)).first->second;
  for (std::size_t i = 0; i < requested.size(); ++i) {
    MapPoint* point = findPoint(requested[i]);
    if (point == nullptr || point->bad) continue;
    // A point requested at two keypoints keeps the last one.
    if (point->observations.contains(stored.id)) detachObservation(*point, stored);
    attachObservation(*point, stored, static_cast<int>(i));
  }
  return stored.id;
}

MapPointId Map::addMapPoint(MapPoint point) {
  if (!point.observations.empty()) {
    throw std::invalid_argument("Map::addMapPoint: add observations with addObservation()");
  }
  const std::lock_guard lock(mutex_);
  point.id = next_point_id_++;
  const MapPointId id = point.id;
  points_.emplace(id, std::move(point));
  return id;
}

bool Map::addObservation(MapPointId point_id, KeyFrameId keyframe_id, int keypoint_index) {
  const std::lock_guard lock(mutex_);
  MapPoint* point = findPoint(point_id);
  KeyFrame* keyframe = findKeyFrame(keyframe_id);
  if (point == nullptr || point->bad || keyframe == nullptr || keypoint_index < 0 ||
      static_cast<std::size_t>(keypoint_index) >= keyframe->keypoints.size()) {
    return false;
  }
  const auto existing = point->observations.find(keyframe_id);
  if (existing != point->observations.end() && existing->second == keypoint_index) return true;
  if (existing != point->observations.end()) detachObservation(*point, *keyframe);
  const MapPointId previous = keyframe->map_points[static_cast<std::size_t>(keypoint_index)];
  if (previous != kNoMapPoint) detachObservation(points_.at(previous), *keyframe);
  attachObservation(*point, *keyframe, keypoint_index);
  return true;
}

bool Map::eraseObservation(MapPointId point_id, KeyFrameId keyframe_id) {
  const std::lock_guard lock(mutex_);
  MapPoint* point = findPoint(point_id);
  KeyFrame* keyframe = findKeyFrame(keyframe_id);
  if (point == nullptr || keyframe == nullptr || !point->observations.contains(keyframe_id)) {
    return false;
  }
  detachObservation(*point, *keyframe);
  return true;
}

std::optional<std::vector<MapPointId>> Map::eraseKeyFrame(KeyFrameId id) {
  const std::lock_guard lock(mutex_);
  KeyFrame* keyframe = findKeyFrame(id);
  if (keyframe == nullptr) return std::nullopt;
  anchorErasedKeyFrame(*keyframe);  // while its covisibility edges are still there
  std::vector<MapPointId> orphans;
  for (const MapPointId point_id : std::vector<MapPointId>(keyframe->map_points)) {
    if (point_id == kNoMapPoint) continue;
    MapPoint& point = points_.at(point_id);
    detachObservation(point, *keyframe);
    if (point.observations.empty()) orphans.push_back(point_id);
  }
  covisibility_.erase(id);
  relinkSuccessor(*keyframe);
  if (newest_keyframe_ == id) newest_keyframe_ = keyframe->previous;
  keyframes_.erase(id);
  std::sort(orphans.begin(), orphans.end());
  return orphans;
}

void Map::anchorErasedKeyFrame(const KeyFrame& erased) {
  KeyFrameId anchor = kNoKeyFrame;
  int best_weight = 0;
  // The row is ordered by id: ties go to the oldest keyframe, the same in every run.
  for (const auto& [other, weight] : covisibility_[erased.id]) {
    if (weight > best_weight) {
      best_weight = weight;
      anchor = other;
    }
  }
  if (anchor == kNoKeyFrame && erased.previous != kNoKeyFrame) anchor = erased.previous;
  if (anchor == kNoKeyFrame) {
    for (const auto& [other_id, other] : keyframes_)
      if (other.previous == erased.id) anchor = other_id;
  }
  if (anchor == kNoKeyFrame) return;  // the map's only keyframe: nothing to follow
  const SE3d& T_b_c = options_.T_b_c.front();
  const SE3d T_w_ca = keyframes_.at(anchor).T_w_b * T_b_c;
  erased_[erased.id] = {anchor, T_w_ca.inverse() * (erased.T_w_b * T_b_c)};
}

void Map::relinkSuccessor(const KeyFrame& erased) {
  for (auto& [other_id, other] : keyframes_) {
    if (other.previous != erased.id) continue;
    other.previous = erased.previous;
    // Nothing before it to integrate from, or no samples from the erased keyframe on (an IMU gap
    // restarted the run): merging would bridge the gap with one interpolated step.
    const bool linked =
        !other.imu_from_previous.empty() && other.imu_from_previous.front().t_ns <= erased.t_ns;
    if (erased.previous == kNoKeyFrame || !linked) {
      other.imu_from_previous.clear();
    } else {
      other.imu_from_previous =
          thinImuSamples(mergeImuSamples(erased.imu_from_previous, other.imu_from_previous),
                         options_.max_imu_samples_per_link);
    }
    return;
  }
}

std::vector<sensors::ImuSample> mergeImuSamples(const std::vector<sensors::ImuSample>& earlier,
                                                const std::vector<sensors::ImuSample>& later) {
  std::vector<sensors::ImuSample> merged = earlier;
  for (const sensors::ImuSample& sample : later) {
    if (merged.empty() || sample.t_ns > merged.back().t_ns) merged.push_back(sample);
  }
  return merged;
}

std::vector<sensors::ImuSample> thinImuSamples(std::vector<sensors::ImuSample> samples,
                                               std::size_t max_samples) {
  if (max_samples < 3) throw OptionError("max_samples", "must be >= 3");
  if (samples.size() <= max_samples) return samples;
  const TimeNs t_first = samples.front().t_ns;
  const double span = static_cast<double>(samples.back().t_ns - t_first);
  const std::size_t bins = max_samples - 2;
  std::vector<sensors::ImuSample> thinned{samples.front()};
  thinned.reserve(max_samples);
  // Sums of the interior samples of the current bin.
  std::size_t bin = 0;
  std::size_t count = 0;
  double t_sum = 0.0;
  sensors::ImuSample sum;
  const auto flush = [&] {
    if (count == 0) return;
    const double n = static_cast<double>(count);
    sensors::ImuSample mean;
    mean.t_ns = t_first + static_cast<TimeNs>(std::llround(t_sum / n));
    mean.gyro = sum.gyro / n;
    mean.accel = sum.accel / n;
    thinned.push_back(mean);
    count = 0;
    t_sum = 0.0;
    sum = sensors::ImuSample{};
  };
  for (std::size_t k = 1; k + 1 < samples.size(); ++k) {
    const double offset = static_cast<double>(samples[k].t_ns - t_first);
    const std::size_t b =
        std::min(bins - 1, static_cast<std::size_t>(offset / span * static_cast<double>(bins)));
    if (b != bin) {
      flush();
      bin = b;
    }
    t_sum += offset;
    sum.gyro += samples[k].gyro;
    sum.accel += samples[k].accel;
    ++count;
  }
  flush();
  thinned.push_back(samples.back());
  return thinned;
}

bool Map::eraseMapPoint(MapPointId id) {
  const std::lock_guard lock(mutex_);
  MapPoint* point = findPoint(id);
  if (point == nullptr) return false;
  detachAllObservations(*point);
  points_.erase(id);
  return true;
}

bool Map::setMapPointBad(MapPointId id) {
  const std::lock_guard lock(mutex_);
  MapPoint* point = findPoint(id);
  if (point == nullptr) return false;
  detachAllObservations(*point);
  point->bad = true;
  return true;
}

int Map::eraseBadMapPoints() {
  const std::lock_guard lock(mutex_);
  return static_cast<int>(
      std::erase_if(points_, [](const auto& entry) { return entry.second.bad; }));
}

bool Map::replaceMapPoint(MapPointId old_id, MapPointId new_id) {
  const std::lock_guard lock(mutex_);
  MapPoint* old_point = findPoint(old_id);
  MapPoint* new_point = findPoint(new_id);
  if (old_id == new_id || old_point == nullptr || new_point == nullptr || new_point->bad) {
    return false;
  }
  const std::map<KeyFrameId, int> old_observations = old_point->observations;
  detachAllObservations(*old_point);
  for (const auto& [keyframe_id, keypoint_index] : old_observations) {
    if (new_point->observations.contains(keyframe_id)) continue;
    attachObservation(*new_point, keyframes_.at(keyframe_id), keypoint_index);
  }
  new_point->visible_count += old_point->visible_count;
  new_point->found_count += old_point->found_count;
  points_.erase(old_id);
  return true;
}

// ---- State -------------------------------------------------------------------------------------

bool Map::setKeyFramePose(KeyFrameId id, const SE3d& T_w_b) {
  const std::lock_guard lock(mutex_);
  KeyFrame* keyframe = findKeyFrame(id);
  if (keyframe == nullptr) return false;
  keyframe->T_w_b = T_w_b;
  return true;
}

bool Map::setKeyFrameInertialState(KeyFrameId id, const Eigen::Vector3d& v_w,
                                   const Eigen::Vector3d& bg, const Eigen::Vector3d& ba) {
  const std::lock_guard lock(mutex_);
  KeyFrame* keyframe = findKeyFrame(id);
  if (keyframe == nullptr) return false;
  keyframe->v_w = v_w;
  keyframe->bg = bg;
  keyframe->ba = ba;
  keyframe->inertial_estimated = true;
  return true;
}

bool Map::rotateKeyFrameVelocity(KeyFrameId id, const Eigen::Matrix3d& R) {
  const std::lock_guard lock(mutex_);
  KeyFrame* keyframe = findKeyFrame(id);
  if (keyframe == nullptr) return false;
  keyframe->v_w = R * keyframe->v_w;
  return true;
}

void Map::transformWorld(const Sim3d& S_new_old) {
  const std::lock_guard lock(mutex_);
  const SE3d& T_b_c = options_.T_b_c.front();
  const SE3d T_c_b = T_b_c.inverse();
  for (auto& [id, keyframe] : keyframes_) {
    keyframe.T_w_b = (S_new_old * (keyframe.T_w_b * T_b_c)) * T_c_b;
    keyframe.v_w = S_new_old.s * (S_new_old.R * keyframe.v_w);
  }
  for (auto& [id, erased] : erased_)
    erased.T_ca_c.t *= S_new_old.s;  // relative: scale only
  for (auto& [id, point] : points_) {
    point.p_w = S_new_old * point.p_w;
    point.normal_w = S_new_old.R * point.normal_w;
    point.min_distance_m *= S_new_old.s;
    point.max_distance_m *= S_new_old.s;
  }
}

KeyFrameCorrection MapCorrection::correctionAt(TimeNs t_ns) const {
  if (keyframes.empty()) return {};
  const auto after = std::upper_bound(
      keyframes.begin(), keyframes.end(), t_ns,
      [](TimeNs t, const KeyFrameCorrection& keyframe) { return t < keyframe.t_ns; });
  return after == keyframes.begin() ? keyframes.front() : *std::prev(after);
}

void Map::recordCorrection(MapCorrection correction) {
  const std::lock_guard lock(mutex_);
  corrections_.push_back(std::move(correction));
}

int Map::correctionCount() const {
  const std::lock_guard lock(mutex_);
  return static_cast<int>(corrections_.size());
}

std::vector<MapCorrection> Map::correctionsSince(int first) const {
  const std::lock_guard lock(mutex_);
  if (first < 0 || first >= static_cast<int>(corrections_.size())) return {};
  return {corrections_.begin() + first, corrections_.end()};
}

bool Map::setMapPointPosition(MapPointId id, const Eigen::Vector3d& p_w) {
  const std::lock_guard lock(mutex_);
  MapPoint* point = findPoint(id);
  if (point == nullptr) return false;
  point->p_w = p_w;
  return true;
}

bool Map::setMapPointDescriptor(MapPointId id, const cv::Mat& descriptor) {
  const std::lock_guard lock(mutex_);
  MapPoint* point = findPoint(id);
  if (point == nullptr) return false;
  point->descriptor = descriptor.clone();
  return true;
}

bool Map::increaseVisible(MapPointId id, int count) {
  const std::lock_guard lock(mutex_);
  MapPoint* point = findPoint(id);
  if (point == nullptr) return false;
  point->visible_count += count;
  return true;
}

bool Map::increaseFound(MapPointId id, int count) {
  const std::lock_guard lock(mutex_);
  MapPoint* point = findPoint(id);
  if (point == nullptr) return false;
  point->found_count += count;
  return true;
}

bool Map::updateDescriptor(MapPointId id) {
  const std::lock_guard lock(mutex_);
  MapPoint* point = findPoint(id);
  if (point == nullptr) return false;
  std::vector<cv::Mat> rows;
  for (const auto& [keyframe_id, keypoint_index] : point->observations) {
    const KeyFrame& keyframe = keyframes_.at(keyframe_id);
    if (!keyframe.descriptors.empty()) rows.push_back(keyframe.descriptors.row(keypoint_index));
  }
  if (rows.empty()) return false;
  const std::size_t n = rows.size();
  const int norm = rows.front().type() == CV_8UC1 ? cv::NORM_HAMMING : cv::NORM_L2;
  std::vector<double> distances(n * n, 0.0);
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t b = a + 1; b < n; ++b) {
      distances[a * n + b] = distances[b * n + a] = cv::norm(rows[a], rows[b], norm);
    }
  }
  std::size_t best = 0;
  double best_median = std::numeric_limits<double>::infinity();
  for (std::size_t a = 0; a < n; ++a) {
    std::vector<double> row(distances.begin() + static_cast<std::ptrdiff_t>(a * n),
                            distances.begin() + static_cast<std::ptrdiff_t>((a + 1) * n));
    std::sort(row.begin(), row.end());
    const double median = row[(n - 1) / 2];  // lower median: includes the zero self-distance
    if (median < best_median) {
      best_median = median;
      best = a;
    }
  }
  point->descriptor = rows[best].clone();
  return true;
}

bool Map::updateNormalAndDistances(MapPointId id) {
  const std::lock_guard lock(mutex_);
  MapPoint* point = findPoint(id);
  if (point == nullptr || point->observations.empty()) return false;
  Eigen::Vector3d normal_sum = Eigen::Vector3d::Zero();
  for (const auto& [keyframe_id, keypoint_index] : point->observations) {
    const KeyFrame& keyframe = keyframes_.at(keyframe_id);
    const int camera = keyframe.keypoints[static_cast<std::size_t>(keypoint_index)].camera;
    const Eigen::Vector3d center_w = (keyframe.T_w_b * options_.T_b_c[camera]).t;
    normal_sum += (point->p_w - center_w).normalized();
  }
  point->normal_w = normal_sum.normalized();

  const auto& [reference_id, reference_index] = *point->observations.begin();
  const KeyFrame& reference = keyframes_.at(reference_id);
  const KeyFrameKeypoint& keypoint = reference.keypoints[static_cast<std::size_t>(reference_index)];
  const Eigen::Vector3d center_w = (reference.T_w_b * options_.T_b_c[keypoint.camera]).t;
  const double distance_m = (point->p_w - center_w).norm();
  point->max_distance_m = distance_m * std::pow(options_.scale_factor, keypoint.octave);
  point->min_distance_m =
      point->max_distance_m / std::pow(options_.scale_factor, options_.num_levels - 1);
  return true;
}

// ---- Queries -----------------------------------------------------------------------------------

std::size_t Map::numKeyFrames() const {
  const std::lock_guard lock(mutex_);
  return keyframes_.size();
}

std::size_t Map::numMapPoints() const {
  const std::lock_guard lock(mutex_);
  return points_.size();
}

std::size_t Map::numCrossClassMapPoints() const {
  const std::lock_guard lock(mutex_);
  const auto classOf = [&](const std::pair<const KeyFrameId, int>& observation) {
    const KeyFrame& keyframe = keyframes_.at(observation.first);
    return keyframe.keypoints[static_cast<std::size_t>(observation.second)].class_id;
  };
  std::size_t count = 0;
  for (const auto& [id, point] : points_) {
    if (point.bad || point.observations.empty()) continue;
    const int first = classOf(*point.observations.begin());
    if (std::any_of(point.observations.begin(), point.observations.end(),
                    [&](const auto& observation) { return classOf(observation) != first; })) {
      ++count;
    }
  }
  return count;
}

bool Map::hasKeyFrame(KeyFrameId id) const {
  const std::lock_guard lock(mutex_);
  return keyframes_.contains(id);
}

bool Map::hasMapPoint(MapPointId id) const {
  const std::lock_guard lock(mutex_);
  return points_.contains(id);
}

std::vector<KeyFrameId> Map::keyFrameIds() const {
  const std::lock_guard lock(mutex_);
  return sortedKeys(keyframes_);
}

KeyFrameId Map::nextKeyFrameId() const {
  const std::lock_guard lock(mutex_);
  return next_keyframe_id_;
}

MapPointId Map::nextMapPointId() const {
  const std::lock_guard lock(mutex_);
  return next_point_id_;
}

KeyFrameId Map::newestKeyFrame() const {
  const std::lock_guard lock(mutex_);
  return newest_keyframe_;
}

KeyFrameId Map::nextKeyFrame(KeyFrameId id) const {
  const std::lock_guard lock(mutex_);
  if (id == kNoKeyFrame || !keyframes_.contains(id)) return kNoKeyFrame;
  for (const auto& [other_id, other] : keyframes_) {
    if (other.previous == id) return other_id;
  }
  return kNoKeyFrame;
}

std::vector<MapPointId> Map::mapPointIds() const {
  const std::lock_guard lock(mutex_);
  std::vector<MapPointId> ids;
  for (const auto& [id, point] : points_) {
    if (!point.bad) ids.push_back(id);
  }
  std::sort(ids.begin(), ids.end());
  return ids;
}

std::optional<KeyFrame> Map::keyFrame(KeyFrameId id) const {
  const std::lock_guard lock(mutex_);
  const auto it = keyframes_.find(id);
  if (it == keyframes_.end()) return std::nullopt;
  return it->second;
}

std::optional<MapPoint> Map::mapPoint(MapPointId id) const {
  const std::lock_guard lock(mutex_);
  const auto it = points_.find(id);
  if (it == points_.end()) return std::nullopt;
  return it->second;
}

std::optional<SE3d> Map::keyFramePose(KeyFrameId id) const {
  const std::lock_guard lock(mutex_);
  const auto it = keyframes_.find(id);
  if (it == keyframes_.end()) return std::nullopt;
  return it->second.T_w_b;
}

std::optional<SE3d> Map::resolvedKeyFramePose(KeyFrameId id) const {
  const std::lock_guard lock(mutex_);
  return resolvePoseLocked(id);
}

std::optional<SE3d> Map::resolvePoseLocked(KeyFrameId id) const {
  if (const auto it = keyframes_.find(id); it != keyframes_.end()) return it->second.T_w_b;
  // Anchors were alive when their keyframe was erased, so each chain ends at a living keyframe
  // (or at one erased without an anchor) after at most as many steps as keyframes were erased.
  SE3d T_c_chain;  // the erased keyframe's camera in the current anchor's camera
  KeyFrameId current = id;
  while (true) {
    const auto erased = erased_.find(current);
    if (erased == erased_.end()) return std::nullopt;
    T_c_chain = erased->second.T_ca_c * T_c_chain;
    current = erased->second.anchor;
    if (const auto it = keyframes_.find(current); it != keyframes_.end()) {
      const SE3d& T_b_c = options_.T_b_c.front();
      return (it->second.T_w_b * T_b_c) * T_c_chain * T_b_c.inverse();
    }
  }
}

std::optional<Eigen::Vector3d> Map::mapPointPosition(MapPointId id) const {
  const std::lock_guard lock(mutex_);
  const auto it = points_.find(id);
  if (it == points_.end()) return std::nullopt;
  return it->second.p_w;
}

// ---- Covisibility ------------------------------------------------------------------------------

int Map::covisibilityWeight(KeyFrameId a, KeyFrameId b) const {
  const std::lock_guard lock(mutex_);
  const auto row = covisibility_.find(a);
  if (row == covisibility_.end()) return 0;
  const auto entry = row->second.find(b);
  return entry == row->second.end() ? 0 : entry->second;
}

std::vector<CovisibleKeyFrame> Map::covisibleKeyFrames(KeyFrameId id, int min_weight) const {
  const std::lock_guard lock(mutex_);
  const auto row = covisibility_.find(id);
  if (row == covisibility_.end()) return {};
  return sortedByWeight(row->second, min_weight);
}

std::vector<KeyFrameId> Map::bestCovisibleKeyFrames(KeyFrameId id, int n) const {
  std::vector<KeyFrameId> best;
  for (const CovisibleKeyFrame& covisible : covisibleKeyFrames(id)) {
    if (static_cast<int>(best.size()) >= n) break;
    best.push_back(covisible.id);
  }
  return best;
}

// ---- Consistency -------------------------------------------------------------------------------

std::unordered_map<KeyFrameId, Map::CovisibilityRow> Map::rebuildCovisibility() const {
  std::unordered_map<KeyFrameId, CovisibilityRow> graph;
  for (const auto& entry : keyframes_)
    graph[entry.first];
  for (const auto& entry : points_) {
    const auto& observations = entry.second.observations;
    for (auto a = observations.begin(); a != observations.end(); ++a) {
      for (auto b = std::next(a); b != observations.end(); ++b) {
        ++graph[a->first][b->first];
        ++graph[b->first][a->first];
      }
    }
  }
  return graph;
}

std::string Map::observationError() const {
  for (const auto& [keyframe_id, keyframe] : keyframes_) {
    if (keyframe.map_points.size() != keyframe.keypoints.size()) {
      return "keyframe " + std::to_string(keyframe_id) + ": map_points size differs";
    }
    for (std::size_t i = 0; i < keyframe.map_points.size(); ++i) {
      const MapPointId point_id = keyframe.map_points[i];
      if (point_id == kNoMapPoint) continue;
      const auto point = points_.find(point_id);
      if (point == points_.end()) return describePair(point_id, keyframe_id) + ": point missing";
      const auto observation = point->second.observations.find(keyframe_id);
      if (observation == point->second.observations.end() ||
          observation->second != static_cast<int>(i)) {
        return describePair(point_id, keyframe_id) + ": keyframe side not mirrored";
      }
      if (!keyframe.keypoints[i].valid()) {
        return describePair(point_id, keyframe_id) + ": observed keypoint is not valid()";
      }
    }
  }
  for (const auto& [point_id, point] : points_) {
    if (point.bad && !point.observations.empty()) {
      return "point " + std::to_string(point_id) + ": bad but observed";
    }
    for (const auto& [keyframe_id, index] : point.observations) {
      const auto keyframe = keyframes_.find(keyframe_id);
      if (keyframe == keyframes_.end()) {
        return describePair(point_id, keyframe_id) + ": keyframe missing";
      }
      const auto& slots = keyframe->second.map_points;
      if (index < 0 || static_cast<std::size_t>(index) >= slots.size() ||
          slots[static_cast<std::size_t>(index)] != point_id) {
        return describePair(point_id, keyframe_id) + ": point side not mirrored";
      }
    }
  }
  return {};
}

std::string Map::covisibilityError() const {
  const auto expected = rebuildCovisibility();
  if (expected.size() != covisibility_.size()) return "covisibility: row count differs";
  for (const auto& [keyframe_id, row] : expected) {
    const auto stored = covisibility_.find(keyframe_id);
    if (stored == covisibility_.end() || stored->second != row) {
      return "covisibility: row of keyframe " + std::to_string(keyframe_id) + " differs";
    }
  }
  return {};
}

std::string Map::consistencyError() const {
  const std::lock_guard lock(mutex_);
  std::string error = observationError();
  return error.empty() ? covisibilityError() : error;
}

// ---- Contents (map files) ----------------------------------------------------------------------

namespace {

std::invalid_argument contentsError(const std::string& what) {
  return std::invalid_argument("map contents: " + what);
}

}  // namespace

std::unique_ptr<Map> Map::fromContents(MapOptions options, MapContents contents) {
  auto map = std::make_unique<Map>(std::move(options));
  map->next_keyframe_id_ = contents.next_keyframe_id;
  map->next_point_id_ = contents.next_point_id;
  std::unordered_map<KeyFrameId, std::vector<MapPointId>> slots;
  for (KeyFrame& keyframe : contents.keyframes) {
    const std::string name = "keyframe " + std::to_string(keyframe.id);
    if (keyframe.id < 0 || keyframe.id >= contents.next_keyframe_id)
      throw contentsError(name + ": id outside [0, " + std::to_string(contents.next_keyframe_id) +
                          ")");
    if (map->keyframes_.contains(keyframe.id)) throw contentsError(name + ": duplicate id");
    if (keyframe.map_points.size() != keyframe.keypoints.size())
      throw contentsError(name + ": " + std::to_string(keyframe.map_points.size()) +
                          " map point slots for " + std::to_string(keyframe.keypoints.size()) +
                          " keypoints");
    try {
      map->validateKeyFrame(keyframe);
    } catch (const std::invalid_argument& e) {
      throw contentsError(name + ": " + e.what());
    }
    slots[keyframe.id] = keyframe.map_points;
    keyframe.map_points.assign(keyframe.keypoints.size(), kNoMapPoint);
    map->newest_keyframe_ = std::max(map->newest_keyframe_, keyframe.id);
    map->covisibility_[keyframe.id];
    const KeyFrameId id = keyframe.id;
    map->keyframes_.emplace(id, std::move(keyframe));
  }
  for (const auto& [id, keyframe] : map->keyframes_) {
    if (keyframe.previous != kNoKeyFrame && !map->keyframes_.contains(keyframe.previous))
      throw contentsError("keyframe " + std::to_string(id) + ": predecessor " +
                          std::to_string(keyframe.previous) + " is not in the map");
  }
  for (MapPoint& point : contents.points) {
    const std::string name = "map point " + std::to_string(point.id);
    if (point.id < 0 || point.id >= contents.next_point_id)
      throw contentsError(name + ": id outside [0, " + std::to_string(contents.next_point_id) +
                          ")");
    if (point.bad) throw contentsError(name + ": flagged bad");
    if (map->points_.contains(point.id)) throw contentsError(name + ": duplicate id");
    const std::map<KeyFrameId, int> observations = std::move(point.observations);
    point.observations.clear();
    MapPoint& stored = map->points_.emplace(point.id, std::move(point)).first->second;
    for (const auto& [keyframe_id, index] : observations) {
      KeyFrame* keyframe = map->findKeyFrame(keyframe_id);
      if (keyframe == nullptr)
        throw contentsError(name + ": observed by unknown keyframe " + std::to_string(keyframe_id));
      if (index < 0 || static_cast<std::size_t>(index) >= keyframe->keypoints.size())
        throw contentsError(name + ": keypoint index " + std::to_string(index) +
                            " outside keyframe " + std::to_string(keyframe_id));
      const std::size_t i = static_cast<std::size_t>(index);
      if (slots[keyframe_id][i] != stored.id || keyframe->map_points[i] != kNoMapPoint ||
          !keyframe->keypoints[i].valid())
        throw contentsError(name + ": keyframe " + std::to_string(keyframe_id) + " keypoint " +
                            std::to_string(index) + " does not observe it");
      map->attachObservation(stored, *keyframe, index);
    }
  }
  for (const auto& [id, keyframe] : map->keyframes_) {
    if (keyframe.map_points != slots[id])
      throw contentsError("keyframe " + std::to_string(id) +
                          ": a map point slot names a point that does not list the observation");
  }
  return map;
}

MapContents Map::contents() const {
  const std::lock_guard lock(mutex_);
  MapContents contents;
  contents.next_keyframe_id = next_keyframe_id_;
  contents.next_point_id = next_point_id_;
  for (const auto& [id, keyframe] : keyframes_)
    contents.keyframes.push_back(keyframe);
  for (const auto& [id, point] : points_)
    if (!point.bad) contents.points.push_back(point);
  std::sort(contents.keyframes.begin(), contents.keyframes.end(),
            [](const KeyFrame& a, const KeyFrame& b) { return a.id < b.id; });
  std::sort(contents.points.begin(), contents.points.end(),
            [](const MapPoint& a, const MapPoint& b) { return a.id < b.id; });
  return contents;
}

}  // namespace superdyna::map

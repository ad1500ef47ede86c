#include "superdyna/mapping/keyframe_culling.h"

#include <algorithm>
#include <utility>

#include "superdyna/core/error.h"

namespace superdyna::mapping {

void KeyFrameCullingOptions::validate() const {
  if (!(redundancy > 0.0 && redundancy <= 1.0)) {
    throw OptionError("mapping.cull_redundancy", "must be in (0, 1]");
  }
  if (min_observers < 1) throw OptionError("mapping.cull_min_observers", "must be >= 1");
  if (keep_newest < 1) throw OptionError("mapping.cull_keep_newest", "must be >= 1");
  if (max_candidates < 1) throw OptionError("mapping.cull_max_candidates", "must be >= 1");
  if (!(max_gap_s > 0.0)) throw OptionError("mapping.cull_max_gap_s", "must be > 0");
  if (!(max_gap_inertial_s > 0.0)) {
    throw OptionError("mapping.cull_max_gap_inertial_s", "must be > 0");
  }
  if (!(max_gap_old_s >= max_gap_inertial_s)) {
    throw OptionError("mapping.cull_max_gap_old_s", "must be >= cull_max_gap_inertial_s");
  }
  if (!(old_after_s > 0.0)) throw OptionError("mapping.cull_old_after_s", "must be > 0");
}

double redundantPointShare(const map::Map& map, map::KeyFrameId id, int min_observers) {
  std::vector<std::pair<map::MapPointId, int>> points;  // (point, octave)
  map.readKeyFrame(id, [&](const map::KeyFrame& kf) {
    for (std::size_t i = 0; i < kf.map_points.size(); ++i) {
      if (kf.map_points[i] != map::kNoMapPoint) {
        points.emplace_back(kf.map_points[i], kf.keypoints[i].octave);
      }
    }
  });
  if (points.empty()) return 0.0;
  int redundant = 0;
  for (const auto& [point_id, octave] : points) {
    std::vector<std::pair<map::KeyFrameId, int>> observers;
    map.readMapPoint(point_id, [&](const map::MapPoint& p) {
      observers.assign(p.observations.begin(), p.observations.end());
    });
    int finer = 0;
    for (const auto& [other, index] : observers) {
      if (other == id) continue;
      map.readKeyFrame(other, [&, index = index, octave = octave](const map::KeyFrame& kf) {
        if (kf.keypoints[static_cast<std::size_t>(index)].octave <= octave + 1) ++finer;
      });
      if (finer >= min_observers) break;
    }
    if (finer >= min_observers) ++redundant;
  }
  return static_cast<double>(redundant) / static_cast<double>(points.size());
}

namespace {

/// The newest `count` keyframes of the temporal chain ending at `newest`.
std::vector<map::KeyFrameId> newestInChain(const map::Map& map, map::KeyFrameId newest, int count) {
  std::vector<map::KeyFrameId> ids;
  map::KeyFrameId id = newest;
  while (id != map::kNoKeyFrame && static_cast<int>(ids.size()) < count) {
    ids.push_back(id);
    map::KeyFrameId previous = map::kNoKeyFrame;
    map.readKeyFrame(id, [&](const map::KeyFrame& kf) { previous = kf.previous; });
    id = previous;
  }
  return ids;
}

/// The largest predecessor-successor gap the removal of `id` may leave [s] (see the header).
double maxGapWithout(const map::Map& map, map::KeyFrameId id, bool in_window, TimeNs newest_t_ns,
                     const KeyFrameCullingOptions& options, const CullingImu& imu) {
  if (imu.inertial_window == 0 || in_window) return options.max_gap_s;
  TimeNs t_ns = newest_t_ns;
  map.readKeyFrame(id, [&](const map::KeyFrame& kf) { t_ns = kf.t_ns; });
  const bool old = nsToSeconds(newest_t_ns - t_ns) > options.old_after_s;
  return old ? options.max_gap_old_s : options.max_gap_inertial_s;
}

/// Time between the predecessor and the successor of `id` [s]; nullopt when either is missing.
std::optional<double> gapWithout(const map::Map& map, map::KeyFrameId id) {
  map::KeyFrameId previous = map::kNoKeyFrame;
  map.readKeyFrame(id, [&](const map::KeyFrame& kf) { previous = kf.previous; });
  const map::KeyFrameId next = map.nextKeyFrame(id);
  TimeNs t_previous = 0;
  TimeNs t_next = 0;
  if (!map.readKeyFrame(previous, [&](const map::KeyFrame& kf) { t_previous = kf.t_ns; }) ||
      !map.readKeyFrame(next, [&](const map::KeyFrame& kf) { t_next = kf.t_ns; })) {
    return std::nullopt;
  }
  return nsToSeconds(t_next - t_previous);
}

}  // namespace

std::vector<map::KeyFrameId> cullRedundantKeyFrames(map::Map& map, map::KeyFrameId newest,
                                                    const KeyFrameCullingOptions& options,
                                                    const CullingImu& imu) {
  if (!options.enabled) return {};
  const std::vector<map::KeyFrameId> ids = map.keyFrameIds();
  if (ids.empty()) return {};
  const map::KeyFrameId first = ids.front();
  const std::vector<map::KeyFrameId> protected_ids =
      newestInChain(map, newest, options.keep_newest);
  const std::vector<map::KeyFrameId> window = newestInChain(map, newest, imu.inertial_window);
  TimeNs newest_t_ns = 0;
  map.readKeyFrame(newest, [&](const map::KeyFrame& kf) { newest_t_ns = kf.t_ns; });
  std::vector<map::KeyFrameId> candidates =
      map.bestCovisibleKeyFrames(newest, options.max_candidates);
  std::sort(candidates.begin(), candidates.end());
  std::vector<map::KeyFrameId> culled;
  for (const map::KeyFrameId id : candidates) {
    if (id == first || std::ranges::find(protected_ids, id) != protected_ids.end()) continue;
    if (imu.has_imu) {
      const std::optional<double> gap = gapWithout(map, id);
      if (!gap) continue;
      const bool in_window = std::ranges::find(window, id) != window.end();
      if (*gap > maxGapWithout(map, id, in_window, newest_t_ns, options, imu)) continue;
    }
    if (redundantPointShare(map, id, options.min_observers) < options.redundancy) continue;
    // One map update: the keyframe and the points only it observed go together.
    const map::Map::UpdateLock update = map.updateLock();
    if (const auto orphans = map.eraseKeyFrame(id)) {
      for (const map::MapPointId point : *orphans)
        map.eraseMapPoint(point);
      culled.push_back(id);
    }
  }
  return culled;
}

}  // namespace superdyna::mapping

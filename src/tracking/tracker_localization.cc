// Localization-only tracking against a loaded map (Tracker::localizeIn): locating a frame in the
// map without a pose prediction and following the keyframes it sees. Self-contained, so that it
// can later share its place search with relocalisation.

#include <algorithm>
#include <map>

#include "superdyna/tracking/tracker.h"

namespace superdyna::tracking {

void Tracker::localizeIn(std::unique_ptr<map::Map> map, int inertial_stages) {
  if (mapping_sink_) mapping_sink_->discardPending();
  map_ = std::move(map);
  runMapping([this] {
    mapper_.reset();
    if (observer_) observer_->mapReset();
  });
  has_map_ = map_->numKeyFrames() > 0;
  localization_only_ = true;
  located_ = false;
  has_last_ = has_motion_ = has_velocity_ = false;
  corrections_followed_ = map_->correctionCount();
  inertial_inits_ = inertial_stages;
  reference_ = map_->newestKeyFrame();
  bias_ = {};
  map_->readKeyFrame(reference_, [&](const map::KeyFrame& kf) { bias_ = {kf.bg, kf.ba}; });
  imu_since_keyframe_.clear();
}

std::vector<map::MapPointId> Tracker::locateInLoadedMap(const Frame& frame,
                                                        TrackingResult& result) {
  result.state = TrackingState::kLocalizing;
  std::vector<map::MapPointId> none(frame.size(), map::kNoMapPoint);
  const double focal_px = 0.5 * (camera0_.fx() + camera0_.fy());
  std::optional<ReferencePose> best;
  map::KeyFrameId best_id = map::kNoKeyFrame;
  for (const map::KeyFrameId id : map_->keyFrameIds()) {
    const std::optional<ReferencePose> pose =
        poseFromReference(frame, referenceView(id), T_b_c0_, focal_px, options_.reference_matching);
    if (pose && (!best || pose->inliers > best->inliers)) {
      best = pose;
      best_id = id;
    }
  }
  if (!best) return none;
  const map::KeyFrameId previous_reference = reference_;
  reference_ = best_id;
  TrackingResult attempt = result;
  const Prediction from_pnp{best->T_w_b, false, std::nullopt,
                            options_.reference_matching.search_radius_px};
  LocalMapTrack track = trackLocalMap(frame, from_pnp, attempt);
  if (attempt.inliers < std::max(options_.min_inliers, options_.reference_matching.min_inliers)) {
    reference_ = previous_reference;
    return none;
  }
  result = attempt;
  result.state = TrackingState::kTracking;
  result.from_reference = true;
  located_ = true;
  t_tracked_ns_ = frame.t_ns;
  followTrackedKeyFrame(track.tracked);
  noteReference(result);
  return std::move(track.tracked);
}

void Tracker::followTrackedKeyFrame(const std::vector<map::MapPointId>& tracked) {
  std::map<map::KeyFrameId, int> shared;
  for (const map::MapPointId id : tracked) {
    if (id == map::kNoMapPoint) continue;
    map_->readMapPoint(id, [&](const map::MapPoint& p) {
      for (const auto& observation : p.observations)
        ++shared[observation.first];
    });
  }
  int most = 0;
  for (const auto& [id, count] : shared) {
    if (count > most) {  // ties: the oldest keyframe
      most = count;
      reference_ = id;
    }
  }
}

}  // namespace superdyna::tracking

// Locating a frame in a map without a usable pose prediction: localization-only tracking of a
// loaded map (Tracker::localizeIn, following the keyframes it sees) and relocalisation after a
// tracking failure (Tracker::relocalize). Both take the best PnP pose against candidate keyframes'
// points (reference_matching.h) and search the local map from it.

#include <algorithm>
#include <map>

#include "superdyna/tracking/tracker.h"

namespace superdyna::tracking {

void Tracker::localizeIn(std::unique_ptr<map::Map> map, int inertial_stages) {
  replaceMap(std::move(map));
  runMapping([this] { mapper_.reset(); });
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

std::optional<Tracker::LocalMapTrack> Tracker::locateAmong(
    const Frame& frame, const std::vector<map::KeyFrameId>& candidates, TrackingResult& result) {
  const double focal_px = 0.5 * (camera0_.fx() + camera0_.fy());
  std::optional<ReferencePose> best;
  map::KeyFrameId best_id = map::kNoKeyFrame;
  for (const map::KeyFrameId id : candidates) {
    const std::optional<ReferencePose> pose =
        poseFromReference(frame, referenceView(id), T_b_c0_, focal_px, options_.reference_matching);
    if (pose && (!best || pose->inliers > best->inliers)) {
      best = pose;
      best_id = id;
    }
  }
  if (!best) return std::nullopt;
  const map::KeyFrameId previous_reference = reference_;
  reference_ = best_id;
  TrackingResult attempt = result;
  const Prediction from_pnp{best->T_w_b, false, std::nullopt,
                            options_.reference_matching.search_radius_px};
  LocalMapTrack track = trackLocalMap(frame, from_pnp, attempt);
  if (attempt.inliers < std::max(options_.min_inliers, options_.reference_matching.min_inliers)) {
    reference_ = previous_reference;
    return std::nullopt;
  }
  attempt.from_reference = true;
  result = attempt;
  return track;
}

std::vector<map::MapPointId> Tracker::locateInLoadedMap(const Frame& frame,
                                                        TrackingResult& result) {
  result.state = TrackingState::kLocalizing;
  std::optional<LocalMapTrack> track = locateAmong(frame, map_->keyFrameIds(), result);
  if (!track) return std::vector<map::MapPointId>(frame.size(), map::kNoMapPoint);
  result.state = TrackingState::kTracking;
  located_ = true;
  t_tracked_ns_ = frame.t_ns;
  followTrackedKeyFrame(track->tracked);
  noteReference(result);
  return std::move(track->tracked);
}

std::optional<std::vector<map::MapPointId>> Tracker::relocalize(const Frame& frame,
                                                                const Prediction& prediction,
                                                                TrackingResult& result) {
  if (static_cast<int>(frame.size()) < options_.reference_matching.min_inliers) {
    return std::nullopt;  // nothing to locate (a black or blank image)
  }
  std::vector<map::KeyFrameId> candidates;
  if (observer_) candidates = observer_->recognizePlace(frame, options_.relocalization_candidates);
  for (const map::KeyFrameId id :
       keyFramesNear(prediction.T_w_b, options_.relocalization_candidates)) {
    if (std::find(candidates.begin(), candidates.end(), id) == candidates.end()) {
      candidates.push_back(id);
    }
  }
  std::optional<LocalMapTrack> track = locateAmong(frame, candidates, result);
  if (!track) return std::nullopt;
  result.relocalized = true;
  ++relocalizations_;
  return countObservations(std::move(*track), true);
}

std::vector<map::KeyFrameId> Tracker::keyFramesNear(const SE3d& T_w_b, int count) const {
  std::vector<std::pair<double, map::KeyFrameId>> by_distance;
  for (const map::KeyFrameId id : map_->keyFrameIds()) {
    if (const std::optional<SE3d> T_w_kf = map_->keyFramePose(id)) {
      by_distance.emplace_back((T_w_kf->t - T_w_b.t).squaredNorm(), id);
    }
  }
  const std::size_t kept = std::min(by_distance.size(), static_cast<std::size_t>(count));
  std::partial_sort(by_distance.begin(), by_distance.begin() + static_cast<std::ptrdiff_t>(kept),
                    by_distance.end());  // ties: the older keyframe first
  std::vector<map::KeyFrameId> nearest;
  for (std::size_t k = 0; k < kept; ++k)
    nearest.push_back(by_distance[k].second);
  return nearest;
}

void Tracker::restartMotionAt(const SE3d& T_w_b, TimeNs t_ns, const Prediction& prediction) {
  T_w_b_last_ = T_w_b;
  t_last_ns_ = t_ns;
  has_last_ = true;
  has_motion_ = false;  // the next frame is matched to the reference keyframe first
  has_velocity_ = prediction.inertial.has_value();
  velocity_w_ = has_velocity_ ? prediction.inertial->v_w : Eigen::Vector3d::Zero();
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

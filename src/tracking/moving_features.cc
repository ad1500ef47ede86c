// The tracker's seam for the moving-object test (dynamic/moving_object_detector.h): between the
// pose prediction and the local-map search.

#include <chrono>
#include <set>

#include "superdyna/core/time.h"
#include "superdyna/tracking/tracker.h"

namespace superdyna::tracking {

namespace {

using Clock = std::chrono::steady_clock;

dynamic::FrameObservations observationsOf(const Frame& frame, bool stereo) {
  dynamic::FrameObservations observations;
  observations.t_ns = frame.t_ns;
  observations.features = &frame.features;
  observations.normalized = &frame.normalized;
  if (stereo) {
    observations.p_c = &frame.p_c0;
    observations.depth_m = &frame.depth_m;
  }
  return observations;
}

}  // namespace

Frame Tracker::removeMovingFeatures(const Frame& frame, const Prediction& prediction,
                                    TrackingResult& result, std::vector<int>& kept) {
  const auto start = Clock::now();
  const bool stereo = !isMonocular();
  const dynamic::FrameObservations current = observationsOf(frame, stereo);
  const bool has_previous = previous_frame_ && has_last_;
  dynamic::FrameObservations previous;
  SE3d T_cur_prev;
  if (has_previous) {
    previous = observationsOf(*previous_frame_, stereo);
    T_cur_prev = (prediction.T_w_b * T_b_c0_).inverse() * (T_w_b_last_ * T_b_c0_);
  }
  result.moving = moving_detector_.detect(has_previous ? &previous : nullptr, current, T_cur_prev);
  if (has_map_) {
    for (const int i : result.moving.moving_previous_keypoints) {
      const map::MapPointId id = previous_tracked_[static_cast<std::size_t>(i)];
      if (id != map::kNoMapPoint && map_->setMapPointBad(id)) ++result.culled_moving_points;
    }
    if (options_.dynamic.cull_points_by_instance) {
      result.culled_moving_points += cullPointsOnMovingInstances(result.moving);
    }
  }
  Frame without = frame.withoutKeypoints(result.moving.drop, &kept);
  result.times.moving_objects_ms = millisecondsSince(start);
  return without;
}

int Tracker::cullPointsOnMovingInstances(const dynamic::MovingObjectReport& report) {
  std::set<int> moving;
  for (const dynamic::ObjectDecision& object : report.objects) {
    if (object.decision == dynamic::ObjectState::kMoving) moving.insert(object.instance_id);
  }
  if (moving.empty()) return 0;
  std::vector<map::MapPointId> culled;
  for (const map::MapPointId id : localPointIds()) {
    map_->readMapPoint(id, [&](const map::MapPoint& point) {
      if (!point.bad && point.instance_id != 0 && moving.count(point.instance_id)) {
        culled.push_back(id);
      }
    });
  }
  for (const map::MapPointId id : culled)
    map_->setMapPointBad(id);
  return static_cast<int>(culled.size());
}

void Tracker::rememberFrame(const Frame& frame, const std::vector<int>& kept,
                            const std::vector<map::MapPointId>& tracked) {
  if (options_.dynamic.mode == dynamic::DynamicMode::kOff) return;
  previous_frame_ = frame;
  previous_tracked_.assign(frame.size(), map::kNoMapPoint);
  for (std::size_t k = 0; k < tracked.size() && k < kept.size(); ++k) {
    previous_tracked_[static_cast<std::size_t>(kept[k])] = tracked[k];
  }
}

}  // namespace superdyna::tracking

#include "superdyna/system/frame_overlays.h"

#include <set>

namespace superdyna::system {

namespace {

/// The instance-id image with only the instances the test found moving (the final mask).
cv::Mat movingOnly(const cv::Mat& ids, const dynamic::MovingObjectReport& report) {
  if (ids.empty()) return ids;
  std::set<int> moving;
  for (const dynamic::ObjectDecision& object : report.objects)
    if (object.decision == dynamic::ObjectState::kMoving) moving.insert(object.instance_id);
  cv::Mat out = ids.clone();
  out.forEach<std::uint16_t>([&](std::uint16_t& id, const int*) {
    if (id != 0 && !moving.count(id)) id = 0;
  });
  return out;
}

}  // namespace

void FrameOverlays::remember(const sensors::FrameBundle& bundle, const tracking::Frame& frame) {
  if (bundle.index % static_cast<std::size_t>(every_) != 0) return;
  Pending pending{bundle.index, bundle.image0, bundle.masks.value_or(sensors::InstanceMasks{}), {}};
  for (const features::Keypoint& k : frame.features.keypoints)
    pending.points.push_back({{k.pixel.x(), k.pixel.y()}, k.class_id, std::nullopt});
  const std::lock_guard lock(mutex_);
  pending_.emplace(bundle.t_ns, std::move(pending));
}

std::optional<FrameOverlay> FrameOverlays::draw(const tracking::TrackingResult& result) {
  std::optional<Pending> pending;
  {
    const std::lock_guard lock(mutex_);
    const auto found = pending_.find(result.t_ns);
    if (found == pending_.end()) return std::nullopt;
    pending = std::move(found->second);
    pending_.erase(found);
  }
  cv::Mat ids = pending->masks.cam0;
  if (moving_objects_) {
    ids = movingOnly(pending->masks.cam0, result.moving);
    const std::vector<char>& drop = result.moving.drop;
    for (std::size_t i = 0; i < pending->points.size() && i < drop.size(); ++i)
      pending->points[i].colour = drop[i] ? cv::Scalar(0, 0, 255) : cv::Scalar(0, 200, 0);
  }
  return FrameOverlay{pending->index,
                      semantics::drawOverlay(pending->image, ids, pending->masks, pending->points)};
}

}  // namespace superdyna::system

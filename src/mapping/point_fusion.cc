#include "superdyna/mapping/point_fusion.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <set>

#include "superdyna/core/error.h"
#include "superdyna/features/matcher.h"

namespace superdyna::mapping {

void PointFusionOptions::validate() const {
  if (neighbours < 0) throw OptionError("mapping.fusion_neighbours", "must be >= 0");
  if (second_neighbours < 0) throw OptionError("mapping.fusion_second_neighbours", "must be >= 0");
  if (!(radius_px > 0.0)) throw OptionError("mapping.fusion_radius_px", "must be > 0");
  if (max_distance < 0) throw OptionError("mapping.fusion_max_distance", "must be >= 0");
  if (!(max_l2_distance >= 0.0)) {
    throw OptionError("mapping.fusion_max_l2_distance", "must be >= 0");
  }
  if (!(reprojection_chi2 > 0.0)) {
    throw OptionError("mapping.fusion_reprojection_chi2", "must be > 0");
  }
  if (!(stereo_chi2 > 0.0)) throw OptionError("mapping.fusion_stereo_chi2", "must be > 0");
  if (!(sigma0_px > 0.0)) throw OptionError("mapping.sigma0_px", "must be > 0");
}

/// A keyframe as fusion needs it: its camera and keypoints, with an index by normalised x.
struct PointFuser::View {
  map::KeyFrame keyframe;
  SE3d T_c_w;
  Eigen::Vector3d centre_w;
  std::vector<std::pair<double, int>> by_x;  ///< (normalised x, keypoint index), sorted.
};

namespace {

double descriptorDistance(const cv::Mat& point, const cv::Mat& rows, int j) {
  if (point.type() == CV_8UC1) {
    return features::hammingDistance(point.ptr<std::uint8_t>(0), rows.ptr<std::uint8_t>(j),
                                     point.cols);
  }
  return features::l2Distance(point.ptr<float>(0), rows.ptr<float>(j), point.cols);
}

std::vector<map::MapPointId> pointsOf(const map::KeyFrame& keyframe) {
  std::set<map::MapPointId> ids;
  for (const map::MapPointId id : keyframe.map_points)
    if (id != map::kNoMapPoint) ids.insert(id);
  return {ids.begin(), ids.end()};
}

}  // namespace

PointFuser::PointFuser(const PointFusionOptions& options, const optim::ReprojectionCamera& camera,
                       double stereo_baseline_m)
    : options_(options),
      camera_(camera),
      focal_px_(0.5 * (camera.fx + camera.fy)),
      stereo_baseline_m_(stereo_baseline_m) {
  options_.validate();
  camera_.validate();
  if (!(stereo_baseline_m >= 0.0) || !std::isfinite(stereo_baseline_m)) {
    throw OptionError("stereo_baseline_m", "must be a finite number >= 0");
  }
}

bool PointFuser::agrees(const Eigen::Vector2d& u, double depth_m, const map::KeyFrameKeypoint& k,
                        double sigma_px) const {
  const Eigen::Vector2d error = focal_px_ * (u - k.normalized);
  const double sigma2 = sigma_px * sigma_px;
  if (!options_.stereo_check || !(stereo_baseline_m_ > 0.0) || !k.hasStereo()) {
    return error.squaredNorm() <= options_.reprojection_chi2 * sigma2;
  }
  // The disparity the point would have against the keypoint's measured one [px].
  const double disparity_error =
      camera_.fx * stereo_baseline_m_ * (1.0 / depth_m - 1.0 / k.depth_m);
  return error.squaredNorm() + disparity_error * disparity_error <= options_.stereo_chi2 * sigma2;
}

std::vector<map::KeyFrameId> PointFuser::targets(const map::Map& map,
                                                 map::KeyFrameId keyframe) const {
  std::vector<map::KeyFrameId> out = map.bestCovisibleKeyFrames(keyframe, options_.neighbours);
  const std::size_t first = out.size();
  for (std::size_t k = 0; k < first; ++k) {
    for (const map::KeyFrameId id :
         map.bestCovisibleKeyFrames(out[k], options_.second_neighbours)) {
      if (id != keyframe && std::find(out.begin(), out.end(), id) == out.end()) out.push_back(id);
    }
  }
  return out;
}

PointFusionResult PointFuser::fuse(map::Map& map, map::KeyFrameId keyframe) const {
  PointFusionResult result;
  if (!options_.enabled) return result;
  const std::optional<map::KeyFrame> current = map.keyFrame(keyframe);
  if (!current) return result;
  const std::vector<map::KeyFrameId> neighbours = targets(map, keyframe);
  const std::vector<map::MapPointId> own = pointsOf(*current);
  std::set<map::MapPointId> theirs;
  for (const map::KeyFrameId id : neighbours) {
    const PointFusionResult r = fuseInto(map, id, own);
    result.merged += r.merged;
    result.added += r.added;
    map.readKeyFrame(id, [&](const map::KeyFrame& kf) {
      for (const map::MapPointId p : kf.map_points)
        if (p != map::kNoMapPoint) theirs.insert(p);
    });
  }
  const PointFusionResult back = fuseInto(map, keyframe, {theirs.begin(), theirs.end()});
  result.merged += back.merged;
  result.added += back.added;
  return result;
}

PointFusionResult PointFuser::fuseInto(map::Map& map, map::KeyFrameId target,
                                       const std::vector<map::MapPointId>& points) const {
  PointFusionResult result;
  View view;
  if (!map.readKeyFrame(target, [&](const map::KeyFrame& kf) { view.keyframe = kf; })) {
    return result;
  }
  const SE3d T_w_c = view.keyframe.T_w_b * camera_.T_b_c;
  view.T_c_w = T_w_c.inverse();
  view.centre_w = T_w_c.t;
  for (std::size_t i = 0; i < view.keyframe.size(); ++i) {
    const Eigen::Vector2d& x = view.keyframe.keypoints[i].normalized;
    if (x.allFinite()) view.by_x.emplace_back(x.x(), static_cast<int>(i));
  }
  std::sort(view.by_x.begin(), view.by_x.end());
  if (view.keyframe.descriptors.empty()) return result;
  for (const map::MapPointId id : points)
    fuseOne(map, view, id, result);
  return result;
}

void PointFuser::fuseOne(map::Map& map, View& view, map::MapPointId point_id,
                         PointFusionResult& result) const {
  const std::optional<map::MapPoint> point = map.mapPoint(point_id);
  if (!point || point->bad || point->descriptor.empty() ||
      point->observations.contains(view.keyframe.id) ||
      point->descriptor.type() != view.keyframe.descriptors.type()) {
    return;
  }
  const Eigen::Vector3d p_c = view.T_c_w * point->p_w;
  if (!(p_c.z() > 0.0) || !map::withinViewingLimits(*point, view.centre_w)) return;
  const Eigen::Vector2d u = p_c.head<2>() / p_c.z();
  const map::MapOptions& pyramid = map.options();
  const int level = map::predictedOctave(*point, (point->p_w - view.centre_w).norm(),
                                         pyramid.scale_factor, pyramid.num_levels);
  const double radius = options_.radius_px * std::pow(pyramid.scale_factor, level) / focal_px_;
  const bool binary = point->descriptor.type() == CV_8UC1;
  const double bound = binary ? options_.max_distance : options_.max_l2_distance;
  int best = -1;
  double best_distance = std::numeric_limits<double>::max();
  auto it = std::lower_bound(view.by_x.begin(), view.by_x.end(),
                             std::make_pair(u.x() - radius, std::numeric_limits<int>::min()));
  for (; it != view.by_x.end() && it->first <= u.x() + radius; ++it) {
    const map::KeyFrameKeypoint& k = view.keyframe.keypoints[static_cast<std::size_t>(it->second)];
    if (std::abs(k.normalized.y() - u.y()) > radius) continue;
    if (pyramid.num_levels > 1 && (k.octave < level - 1 || k.octave > level)) continue;
    if (options_.same_class_only && k.class_id != point->class_id) continue;
    const double sigma = optim::octaveSigmaPx(k.octave, options_.sigma0_px, pyramid.scale_factor);
    if (!agrees(u, p_c.z(), k, sigma)) continue;
    const double d = descriptorDistance(point->descriptor, view.keyframe.descriptors, it->second);
    if (d < best_distance) {
      best_distance = d;
      best = it->second;
    }
  }
  if (best < 0 || best_distance > bound) return;
  map::MapPointId& slot = view.keyframe.map_points[static_cast<std::size_t>(best)];
  map::MapPointId survivor = point_id;
  const map::Map::UpdateLock update = map.updateLock();  // one map update per fused point
  if (slot == map::kNoMapPoint) {
    if (!map.addObservation(point_id, view.keyframe.id, best)) return;
    ++result.added;
  } else {
    const std::optional<map::MapPoint> other = map.mapPoint(slot);
    if (!other || other->bad) return;
    const bool keep_other = other->numObservations() > point->numObservations();
    survivor = keep_other ? slot : point_id;
    if (!map.replaceMapPoint(keep_other ? point_id : slot, survivor)) return;
    ++result.merged;
  }
  slot = survivor;
  map.updateNormalAndDistances(survivor);
}

}  // namespace superdyna::mapping

// The monocular parts of the Tracker: two-view map initialisation, the motion model it leaves
// behind.

#include <algorithm>
#include <cmath>

#include "superdyna/tracking/tracker.h"

namespace superdyna::tracking {

void Tracker::initializeMono(const Frame& frame, TrackingResult& result) {
  result.state = TrackingState::kInitializing;
  if (const auto init = mono_initializer_->addFrame(frame, gyroRotationSinceReference(frame))) {
    buildMonoMap(*init, frame, result);
  }
}

std::optional<Eigen::Matrix3d> Tracker::gyroRotationSinceReference(const Frame& frame) const {
  if (!imu_ || !mono_initializer_->hasReference()) return std::nullopt;
  const TimeNs t0_ns = mono_initializer_->referenceTime();
  const std::vector<sensors::ImuSample>& samples = imu_since_keyframe_.samples();
  if (samples.size() < 2 || samples.front().t_ns > t0_ns || samples.back().t_ns < frame.t_ns ||
      frame.t_ns <= t0_ns) {
    return std::nullopt;  // the samples do not span the two views
  }
  imu::Preintegration preintegration(bias_, imu::ImuNoise::fromCalibration(*imu_));
  preintegration.integrateBetween(samples, t0_ns, frame.t_ns);
  const Eigen::Matrix3d R_b_i = imu_->T_b_i.rotation();
  const Eigen::Matrix3d R_b0_b1 = R_b_i * preintegration.deltaRotation() * R_b_i.transpose();
  const Eigen::Matrix3d R_b_c = T_b_c0_.rotation();
  return R_b_c.transpose() * R_b0_b1 * R_b_c;
}

bool Tracker::buildMonoMap(const MonoInitialization& init, const Frame& frame,
                           TrackingResult& result) {
  // A new map after a loss keeps the world frame of the lost one (at the last predicted pose).
  const SE3d T_w_b0 = map_->numKeyFrames() > 0 ? T_w_b_last_ : gravityAlignedPose(init.reference);
  const SE3d T_w_c0 = T_w_b0 * T_b_c0_;
  const SE3d T_w_b1 = T_w_c0 * init.T_c0_c1 * T_b_c0_.inverse();
  startMap(init.reference, T_w_b0);
  const map::KeyFrameId first = reference_;
  SE3d pose1 = T_w_b1;
  const map::KeyFrameId second =
      insertKeyFrame(frame, pose1, std::vector<map::MapPointId>(frame.size(), map::kNoMapPoint));
  for (const MonoInitialization::Point& p : init.points) {
    const auto current = static_cast<std::size_t>(p.current_index);
    map::MapPoint point;
    point.p_w = T_w_c0 * p.p_c0;
    point.descriptor = frame.features.descriptors.row(p.current_index).clone();
    point.class_id = frame.features.keypoints[current].class_id;
    point.instance_id = frame.features.keypoints[current].instance_id;
    const map::MapPointId id = map_->addMapPoint(std::move(point));
    map_->addObservation(id, first, p.reference_index);
    map_->addObservation(id, second, p.current_index);
    map_->updateNormalAndDistances(id);
  }
  // With two keyframes the local BA (first one fixed) is the global BA of the new map.
  runMapping([this, map = map_.get(), second] { mapper_.processKeyFrame(*map, second); });
  waitForMapping();
  if (static_cast<int>(map_->numMapPoints()) < options_.mono_init.min_triangulated) {
    map_ = newMap();  // BA removed too much: keep initialising from the next frames
    has_map_ = false;
    return false;
  }
  normalizeMonoScale(first);
  result.state = TrackingState::kInitialized;
  result.keyframe = true;
  result.T_w_b = map_->keyFramePose(second).value_or(T_w_b1);
  setMotionFromInitialization(map_->keyFramePose(first).value_or(T_w_b0), init.reference.t_ns,
                              result.T_w_b, frame.t_ns);
  return true;
}

void Tracker::normalizeMonoScale(map::KeyFrameId first) {
  const SE3d T_w_c0 = map_->keyFramePose(first).value_or(SE3d()) * T_b_c0_;
  const SE3d T_c0_w = T_w_c0.inverse();
  std::vector<map::MapPointId> ids;
  map_->readKeyFrame(first, [&](const map::KeyFrame& kf) { ids = kf.map_points; });
  std::vector<double> depths;
  for (const map::MapPointId id : ids) {
    if (id == map::kNoMapPoint) continue;
    if (const auto p = map_->mapPointPosition(id)) depths.push_back((T_c0_w * *p).z());
  }
  if (depths.empty()) return;
  const auto middle = depths.begin() + static_cast<std::ptrdiff_t>(depths.size() / 2);
  std::nth_element(depths.begin(), middle, depths.end());
  if (!(*middle > 0.0)) return;
  // Scale about the first camera centre so that its median scene depth is 1.
  Sim3d S;
  S.s = 1.0 / *middle;
  S.t = T_w_c0.t - S.s * T_w_c0.t;
  map_->transformWorld(S);
}

void Tracker::setMotionFromInitialization(const SE3d& T_w_b0, TimeNs t0_ns, const SE3d& T_w_b1,
                                          TimeNs t1_ns) {
  // The two views are several frames apart: the constant-velocity model gets the per-frame share.
  const TimeNs frame_period = has_last_ && t1_ns > t_last_ns_ ? t1_ns - t_last_ns_ : t1_ns - t0_ns;
  const double steps =
      std::max(1.0, std::round(static_cast<double>(t1_ns - t0_ns) /
                               static_cast<double>(std::max<TimeNs>(frame_period, 1))));
  const SE3d relative = T_w_b0.inverse() * T_w_b1;
  motion_ = SE3d(expSO3(logSO3(relative.rotation()) / steps), relative.t / steps);
  has_motion_ = true;
  has_velocity_ = false;  // the map has no metric scale yet
  T_w_b_last_ = T_w_b1;
  t_last_ns_ = t1_ns;
  has_last_ = true;
}

}  // namespace superdyna::tracking

#include "superdyna/mapping/map_inertial_alignment.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "superdyna/core/error.h"

namespace superdyna::mapping {

SE3d transformBodyPose(const Sim3d& S_new_old, const SE3d& T_w_b, const SE3d& T_b_c) {
  return (S_new_old * (T_w_b * T_b_c)) * T_b_c.inverse();
}

void transformMap(map::Map& map, const Sim3d& S_new_old, const SE3d& T_b_c) {
  for (const map::KeyFrameId id : map.keyFrameIds()) {
    const auto kf = map.keyFrame(id);
    map.setKeyFramePose(id, transformBodyPose(S_new_old, kf->T_w_b, T_b_c));
    map.setKeyFrameInertialState(id, S_new_old.s * (S_new_old.R * kf->v_w), kf->bg, kf->ba);
  }
  const std::vector<map::MapPointId> points = map.mapPointIds();
  for (const map::MapPointId id : points) {
    if (const auto p = map.mapPointPosition(id)) map.setMapPointPosition(id, S_new_old * *p);
  }
  for (const map::MapPointId id : points)
    map.updateNormalAndDistances(id);
}

namespace {

/// The samples from the last one at or before t0 to the first one at or after t1; empty when the
/// samples do not cover [t0, t1].
std::span<const io::ImuSample> samplesCovering(std::span<const io::ImuSample> samples, TimeNs t0,
                                               TimeNs t1) {
  const auto before = [](const io::ImuSample& s, TimeNs t) { return s.t_ns < t; };
  auto first = std::lower_bound(samples.begin(), samples.end(), t0, before);
  auto last = std::lower_bound(samples.begin(), samples.end(), t1, before);
  if (last == samples.end()) return {};
  if (first == samples.end() || first->t_ns > t0) {
    if (first == samples.begin()) return {};
    --first;
  }
  return {first, last + 1};
}

}  // namespace

std::optional<MapInertialAlignment> alignMapWithInertial(
    map::Map& map, std::span<const io::ImuSample> samples, const io::ImuCalibration& imu,
    const SE3d& T_b_c, const imu::Bias& initial_bias, const imu::InertialInitOptions& options) {
  const std::vector<map::KeyFrameId> ids = map.keyFrameIds();
  if (ids.size() < 3) return std::nullopt;
  imu::InertialInitInput input;
  std::vector<TimeNs> times;
  for (const map::KeyFrameId id : ids) {
    const auto kf = map.keyFrame(id);
    input.T_v_b.push_back(kf->T_w_b * imu.T_b_i);  // the estimation works in the IMU frame
    times.push_back(kf->t_ns);
  }
  const imu::ImuNoise noise = imu::ImuNoise::fromCalibration(imu);
  for (std::size_t k = 0; k + 1 < times.size(); ++k) {
    const auto span = samplesCovering(samples, times[k], times[k + 1]);
    if (span.empty() || !(times[k + 1] > times[k])) return std::nullopt;
    imu::Preintegration preintegration(initial_bias, noise);
    preintegration.integrateBetween(span, times[k], times[k + 1]);
    input.preintegrations.push_back(std::move(preintegration));
  }
  MapInertialAlignment alignment;
  try {
    alignment.inertial = imu::initializeInertial(input, options);
  } catch (const std::runtime_error&) {
    return std::nullopt;  // a failed solve leaves the visual map as it was
  }
  const imu::InertialInitResult& r = alignment.inertial;
  if (!(r.scale > 0.0) || !std::isfinite(r.scale) || !r.R_w_v.allFinite()) return std::nullopt;
  // Scale and rotate about the first keyframe's camera centre, which stays where it is.
  const Eigen::Vector3d c0 = (map.keyFramePose(ids.front()).value_or(SE3d()) * T_b_c).t;
  alignment.S_w_v.s = r.scale;
  alignment.S_w_v.R = r.R_w_v;
  alignment.S_w_v.t = c0 - r.scale * (r.R_w_v * c0);
  transformMap(map, alignment.S_w_v, T_b_c);
  // Velocities are metric already: only rotate them. The IMU origin's velocity is the body's
  // up to the lever-arm term, which the rotation rates of a MAV make negligible here.
  for (std::size_t k = 0; k < ids.size(); ++k) {
    map.setKeyFrameInertialState(ids[k], r.R_w_v * r.v_v[k], r.bias.bg, r.bias.ba);
  }
  return alignment;
}

}  // namespace superdyna::mapping

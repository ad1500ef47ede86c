#pragma once
// A synthetic keyframe map for the mapping tests: keyframes on the lively test motion with the
// simulated IMU samples between them, landmarks on a sphere around the motion observed by a
// forward camera at the body origin, and the ground truth to compare against.

#include <random>
#include <vector>

#include "imu/imu_test_motion.h"
#include "superdyna/map/map.h"
#include "superdyna/optim/reprojection_factor.h"

namespace superdyna::test {

struct TruthState {
  SE3d T_w_b;
  Eigen::Vector3d v_w;
  imu::Bias bias;
};

struct MappingScene {
  std::unique_ptr<map::Map> map;
  std::vector<map::KeyFrameId> ids;
  std::vector<TruthState> truth;  ///< Per keyframe (world frame, z up).
  std::vector<Eigen::Vector3d> landmarks;
  std::vector<map::MapPointId> point_ids;
  optim::ReprojectionCamera camera;
  imu::ImuNoise noise;
};

struct SceneOptions {
  int keyframes = 12;
  double spacing_s = 0.25;
  bool imu_noise = false;  ///< Simulator noise and bias random walk (else exact + constant bias).
  /// The map is stored in the frame v = T_v_w (world) with lengths divided by `scale`.
  SE3d T_v_w;
  double scale = 1.0;
  int landmarks = 300;
};

inline MappingScene makeMappingScene(const SceneOptions& options) {
  const double duration_s = options.keyframes * options.spacing_s + 0.6;
  const sim::Se3Spline motion = livelyMotion(duration_s);
  sim::ImuNoiseOptions imu_options;
  imu_options.noise = options.imu_noise;
  const sim::ImuSequence imu =
      sim::ImuSimulator(imu_options)
          .simulate(motion, {kMotionStartNs, kMotionStartNs + secondsToNs(duration_s - 0.1)});
  const std::vector<sensors::ImuSample> samples = toImuSamples(imu.measurements);

  MappingScene scene;
  scene.noise = noiseOf(imu_options);
  scene.camera.fx = scene.camera.fy = 400.0;
  map::MapOptions map_options;
  scene.map = std::make_unique<map::Map>(map_options);
  std::mt19937 rng(7);
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (int k = 0; k < options.landmarks; ++k) {
    const Eigen::Vector3d direction =
        Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    scene.landmarks.push_back(Eigen::Vector3d(0.0, 0.0, 1.5) + (5.0 + gauss(rng)) * direction);
  }
  const auto to_v = [&](const Eigen::Vector3d& p_w) -> Eigen::Vector3d {
    return (options.T_v_w * p_w) / options.scale;
  };
  for (const Eigen::Vector3d& p_w : scene.landmarks) {
    map::MapPoint point;
    point.p_w = to_v(p_w);
    scene.point_ids.push_back(scene.map->addMapPoint(point));
  }

  TimeNs t_previous = 0;
  for (int k = 0; k < options.keyframes; ++k) {
    const TimeNs t_ns = kMotionStartNs + secondsToNs(0.2 + k * options.spacing_s);
    const sim::Se3SplineState s = motion.state(t_ns);
    std::size_t m = 0;
    while (m + 1 < imu.states.size() && imu.states[m + 1].t_ns <= t_ns)
      ++m;
    scene.truth.push_back({s.T_w_b, s.v_w, {imu.states[m].bg, imu.states[m].ba}});

    map::KeyFrame kf;
    kf.t_ns = t_ns;
    SE3d T_v_b = options.T_v_w * s.T_w_b;
    T_v_b.t /= options.scale;
    kf.T_w_b = T_v_b;
    if (k > 0) {
      for (const sensors::ImuSample& sample : samples) {
        const bool after_start = sample.t_ns > t_previous - secondsToNs(0.005);
        const bool before_end = sample.t_ns < t_ns + secondsToNs(0.005);
        if (after_start && before_end) kf.imu_from_previous.push_back(sample);
      }
    }
    std::vector<std::pair<int, Eigen::Vector2d>> seen;
    for (std::size_t p = 0; p < scene.landmarks.size(); ++p) {
      const Eigen::Vector3d p_c = s.T_w_b.inverse() * scene.landmarks[p];
      if (p_c.z() < 0.5) continue;
      const Eigen::Vector2d xy = p_c.head<2>() / p_c.z();
      if (xy.cwiseAbs().maxCoeff() > 0.8) continue;
      seen.emplace_back(static_cast<int>(p), xy);
    }
    for (const auto& [p, xy] : seen) {
      map::KeyFrameKeypoint keypoint;
      keypoint.normalized = xy;
      keypoint.pixel = 400.0 * xy;
      kf.keypoints.push_back(keypoint);
    }
    const map::KeyFrameId id = scene.map->addKeyFrame(std::move(kf));
    for (std::size_t i = 0; i < seen.size(); ++i) {
      scene.map->addObservation(scene.point_ids[static_cast<std::size_t>(seen[i].first)], id,
                                static_cast<int>(i));
    }
    scene.ids.push_back(id);
    t_previous = t_ns;
  }
  for (const map::MapPointId id : scene.point_ids)
    scene.map->updateNormalAndDistances(id);
  return scene;
}

/// Angle between the gravity directions seen from the body frames of two poses [deg].
inline double tiltDifferenceDeg(const SE3d& a, const SE3d& b) {
  const Eigen::Vector3d down(0.0, 0.0, -1.0);
  const Eigen::Vector3d da = a.q.inverse() * down;
  const Eigen::Vector3d db = b.q.inverse() * down;
  return std::acos(std::clamp(da.dot(db), -1.0, 1.0)) * 180.0 / M_PI;
}

}  // namespace superdyna::test

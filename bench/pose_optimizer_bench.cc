// Motion-only bundle adjustment (PoseOptimizer) on a synthetic frame of the size tracking sees:
// 300 matches of a stereo rig (two thirds stereo, 10 % gross outliers) with 1 px noise, from a
// prediction 2 cm and 0.5 deg off. Tracking runs it once per frame (twice with
// tracker.refine_radius_px), so its cost is a fixed share of every frame.
//
//   build/bin/superdyna_bench --benchmark_filter=PoseOptimizer

#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "superdyna/optim/pose_optimizer.h"

namespace {

using superdyna::SE3d;
using superdyna::optim::PoseObservation;
using superdyna::optim::PoseOptimizer;
using superdyna::optim::ReprojectionCamera;

constexpr double kFocalPx = 450.0;
constexpr double kCxPx = 376.0;
constexpr double kCyPx = 240.0;

struct Frame {
  std::vector<ReprojectionCamera> cameras;
  std::vector<PoseObservation> observations;
  SE3d T_w_b_predicted;
};

Frame makeFrame(int num_matches) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u_px(0.0, 2.0 * kCxPx), v_px(0.0, 2.0 * kCyPx);
  std::uniform_real_distribution<double> depth_m(1.0, 15.0), fraction(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 1.0);
  Frame frame;
  ReprojectionCamera camera;
  camera.fx = camera.fy = kFocalPx;
  camera.baseline_m = 0.11;
  frame.cameras = {camera};
  for (int i = 0; i < num_matches; ++i) {
    const Eigen::Vector2d pixel(u_px(rng), v_px(rng));
    const double depth = depth_m(rng);
    const Eigen::Vector3d p_c = depth * Eigen::Vector3d((pixel.x() - kCxPx) / kFocalPx,
                                                        (pixel.y() - kCyPx) / kFocalPx, 1.0);
    const bool outlier = fraction(rng) < 0.1;
    const Eigen::Vector2d observed = outlier ? Eigen::Vector2d(u_px(rng), v_px(rng))
                                             : pixel + Eigen::Vector2d(noise(rng), noise(rng));
    PoseObservation observation;
    observation.p_w = p_c;  // the true pose is the identity
    observation.normalized = (observed - Eigen::Vector2d(kCxPx, kCyPx)) / kFocalPx;
    observation.octave = static_cast<int>(fraction(rng) * 4.0);
    if (fraction(rng) < 2.0 / 3.0) {
      const double right_u = kFocalPx * (p_c.x() - camera.baseline_m) / p_c.z() + kCxPx;
      observation.right_x = (right_u + noise(rng) - kCxPx) / kFocalPx;
    }
    frame.observations.push_back(observation);
  }
  frame.T_w_b_predicted = SE3d(superdyna::expSO3(Eigen::Vector3d(0.005, -0.006, 0.004)),
                               Eigen::Vector3d(0.012, -0.01, 0.012));
  return frame;
}

void BM_PoseOptimizer(benchmark::State& state) {
  const Frame frame = makeFrame(static_cast<int>(state.range(0)));
  const PoseOptimizer optimizer;
  int inliers = 0;
  for (auto _ : state) {
    const auto result =
        optimizer.optimize(frame.T_w_b_predicted, frame.cameras, frame.observations);
    inliers = result.num_inliers;
    benchmark::DoNotOptimize(result.T_w_b.t.data());
  }
  state.counters["inliers"] = inliers;
}
BENCHMARK(BM_PoseOptimizer)->Arg(100)->Arg(300)->Arg(600)->Unit(benchmark::kMillisecond);

}  // namespace

// Speed of the moving-object test (the paper's Table 12 row "moving objects identifying") on real
// frames of a simulated sequence with instance masks: baseline_frames + 1 consecutive frames (the
// default options') are prepared by the front end (ORB, stereo, class-wise), the test is primed on
// all but the last (tracks, the chains of the longest baseline) and timed on the last pair, with
// the ground-truth relative pose as the prediction.
// Usage: build/bin/superdyna_dynamic_bench [benchmark options]; the sequence is
// $SUPERDYNA_BENCH_SEQUENCE (a folder holding mav0/, e.g. from `superdyna simulate --dynamic
// high`), the last frame $SUPERDYNA_BENCH_FRAME (default 140). BM_ProjectionMatching times the
// frame-to-frame matching of the last two, class-wise or not.

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "superdyna/dynamic/moving_object_detector.h"
#include "superdyna/features/matcher.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/tracking/front_end.h"

namespace {

using namespace superdyna;

struct Frames {
  std::vector<tracking::Frame> frames;
  std::vector<SE3d> T_w_c;
  CameraModel camera;
};

const Frames* loadFrames() {
  static std::optional<Frames> loaded;
  static bool tried = false;
  if (tried) return loaded ? &*loaded : nullptr;
  tried = true;
  const char* path = std::getenv("SUPERDYNA_BENCH_SEQUENCE");
  if (!path) {
    std::cerr << "set SUPERDYNA_BENCH_SEQUENCE to a simulated sequence with instance masks\n";
    return nullptr;
  }
  const char* frame_env = std::getenv("SUPERDYNA_BENCH_FRAME");
  const std::size_t last = frame_env ? std::stoul(frame_env) : 140;
  io::DatasetSourceOptions options;
  options.inertial = false;
  options.instance_masks = true;
  const int frames = dynamic::MovingObjectOptions().baseline_frames + 1;
  options.first_frame = last - static_cast<std::size_t>(frames - 1);
  options.max_frames = static_cast<std::size_t>(frames);
  const auto source = io::openDataset(io::DatasetKind::kEuroc, path, options);
  Frames out;
  tracking::FrontEndOptions front;
  front.stereo.same_class_only = true;
  tracking::FrontEnd front_end(front, source->camera0(), source->camera1());
  out.camera = source->camera0().cameraModel();
  while (auto bundle = source->next()) {
    out.frames.push_back(front_end.build(*bundle));
    out.T_w_c.push_back(*bundle->T_w_b_gt * source->camera0().T_b_c);
  }
  loaded = std::move(out);
  return &*loaded;
}

dynamic::FrameObservations view(const tracking::Frame& frame) {
  dynamic::FrameObservations v;
  v.t_ns = frame.t_ns;
  v.features = &frame.features;
  v.normalized = &frame.normalized;
  v.p_c = &frame.p_c0;
  v.depth_m = &frame.depth_m;
  return v;
}

void BM_MovingObjectTest(benchmark::State& state) {
  const Frames* f = loadFrames();
  if (!f) {
    state.SkipWithError("no sequence (SUPERDYNA_BENCH_SEQUENCE)");
    return;
  }
  dynamic::MovingObjectOptions options;
  options.mode = dynamic::DynamicMode::kSemanticGeometric;
  options.geometric = state.range(0) != 0;
  dynamic::MovingObjectDetector primed(options, f->camera);
  const std::size_t last = f->frames.size() - 1;
  std::vector<dynamic::FrameObservations> views;
  for (const tracking::Frame& frame : f->frames)
    views.push_back(view(frame));
  primed.detect(nullptr, views[0], SE3d());
  for (std::size_t k = 1; k < last; ++k)
    primed.detect(&views[k - 1], views[k], f->T_w_c[k].inverse() * f->T_w_c[k - 1]);
  const SE3d T = f->T_w_c[last].inverse() * f->T_w_c[last - 1];
  int objects = 0;
  for (auto _ : state) {
    dynamic::MovingObjectDetector detector = primed;
    const dynamic::MovingObjectReport report = detector.detect(&views[last - 1], views[last], T);
    objects = static_cast<int>(report.objects.size());
    benchmark::DoNotOptimize(report.dropped);
  }
  state.counters["keypoints"] = static_cast<double>(f->frames[last].size());
  state.counters["objects"] = objects;
}
BENCHMARK(BM_MovingObjectTest)->Arg(0)->Arg(1)->ArgName("geometric")->Unit(benchmark::kMillisecond);

/// Frame-to-frame matching by projection as tracking does it (the previous frame's stereo points
/// projected with the true motion, 15 px radius), class-wise (the paper's matching within a
/// class) or not: the cost class-wise matching adds or saves.
void BM_ProjectionMatching(benchmark::State& state) {
  const Frames* f = loadFrames();
  if (!f) {
    state.SkipWithError("no sequence (SUPERDYNA_BENCH_SEQUENCE)");
    return;
  }
  const std::size_t last = f->frames.size() - 1;
  const tracking::Frame& previous = f->frames[last - 1];
  const tracking::Frame& current = f->frames[last];
  const SE3d T_c2_c1 = f->T_w_c[last].inverse() * f->T_w_c[last - 1];
  std::vector<Eigen::Vector2d> predicted(previous.size(), Eigen::Vector2d::Constant(NAN));
  for (std::size_t i = 0; i < previous.size(); ++i) {
    if (!(previous.depth_m[i] > 0.0)) continue;
    if (const auto pixel = f->camera.project(T_c2_c1 * previous.p_c0[i])) predicted[i] = *pixel;
  }
  const features::KeypointGrid grid(current.features.keypoints, current.features.image_size);
  features::ProjectionMatchOptions options;
  options.same_class_only = state.range(0) != 0;
  std::size_t matches = 0;
  for (auto _ : state) {
    const auto found =
        features::matchByProjection(previous.features, predicted, current.features, grid, options);
    matches = found.size();
    benchmark::DoNotOptimize(found.data());
  }
  state.counters["matches"] = static_cast<double>(matches);
}
BENCHMARK(BM_ProjectionMatching)
    ->Arg(0)
    ->Arg(1)
    ->ArgName("class_wise")
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();

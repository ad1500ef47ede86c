// Speed of the moving-object test (the paper's Table 12 row "moving objects identifying") on real
// frames of a simulated sequence with instance masks: three consecutive frames are prepared by the
// front end (ORB, stereo, class-wise), the test is primed on the first two (tracks, two-frame
// links) and timed on the last pair, with the ground-truth relative pose as the prediction.
// Usage: build/bin/superdyna_dynamic_bench [benchmark options]; the sequence is
// $SUPERDYNA_BENCH_SEQUENCE (a folder holding mav0/, e.g. from `superdyna simulate --dynamic
// high`), frames $SUPERDYNA_BENCH_FRAME (default 140) - 2 to that one.

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "superdyna/dynamic/moving_object_detector.h"
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
  options.first_frame = last - 2;
  options.max_frames = 3;
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
  const auto v0 = view(f->frames[0]), v1 = view(f->frames[1]), v2 = view(f->frames[2]);
  primed.detect(nullptr, v0, SE3d());
  primed.detect(&v0, v1, f->T_w_c[1].inverse() * f->T_w_c[0]);
  const SE3d T = f->T_w_c[2].inverse() * f->T_w_c[1];
  int objects = 0;
  for (auto _ : state) {
    dynamic::MovingObjectDetector detector = primed;
    const dynamic::MovingObjectReport report = detector.detect(&v1, v2, T);
    objects = static_cast<int>(report.objects.size());
    benchmark::DoNotOptimize(report.dropped);
  }
  state.counters["keypoints"] = static_cast<double>(f->frames[2].size());
  state.counters["objects"] = objects;
}
BENCHMARK(BM_MovingObjectTest)->Arg(0)->Arg(1)->ArgName("geometric")->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();

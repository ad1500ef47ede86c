// Speed of the front end on real 752x480 EuRoC frames (../shared/data/euroc/V1_01_easy_micro, or
// SUPERDYNA_BENCH_EUROC): ORB extraction, ORB extraction + unrectified stereo matching of a pair,
// and XFeat extraction (model from $SUPERDYNA_MODEL_DIR or ../shared/models). A benchmark whose
// data or model is absent reports why and is skipped.
//
//   build/bin/superdyna_bench [--benchmark_filter=Orb] [--benchmark_repetitions=5]

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "superdyna/features/orb_extractor.h"
#include "superdyna/features/stereo_matcher.h"
#include "superdyna/features/xfeat_extractor.h"
#include "superdyna/io/dataset_source.h"

namespace {

namespace fs = std::filesystem;
using namespace superdyna;

fs::path fromEnvironmentOr(const char* variable, const fs::path& fallback) {
  const char* value = std::getenv(variable);
  return value != nullptr && *value != '\0' ? fs::path(value) : fallback;
}

/// One stereo frame of the EuRoC excerpt with its calibration, loaded once.
struct StereoSample {
  io::FrameBundle frame;
  io::CameraCalibration cam0, cam1;
};

const std::optional<StereoSample>& stereoSample() {
  static const std::optional<StereoSample> sample = []() -> std::optional<StereoSample> {
    const fs::path path = fromEnvironmentOr(
        "SUPERDYNA_BENCH_EUROC", fs::path(SUPERDYNA_SHARED_DIR) / "data/euroc/V1_01_easy_micro");
    if (!fs::exists(path)) return std::nullopt;
    io::DatasetSourceOptions options;
    options.inertial = false;
    const auto source = io::openDataset(io::DatasetKind::kEuroc, path, options);
    return StereoSample{*source->next(), source->camera0(), *source->camera1()};
  }();
  return sample;
}

void BM_OrbExtract(benchmark::State& state) {
  const auto& sample = stereoSample();
  if (!sample) return state.SkipWithError("EuRoC excerpt not found (SUPERDYNA_BENCH_EUROC)");
  features::OrbExtractor extractor;
  for (auto _ : state)
    benchmark::DoNotOptimize(extractor.extract(sample->frame.image0));
}
BENCHMARK(BM_OrbExtract)->Unit(benchmark::kMillisecond);

void BM_OrbStereoPair(benchmark::State& state) {
  const auto& sample = stereoSample();
  if (!sample) return state.SkipWithError("EuRoC excerpt not found (SUPERDYNA_BENCH_EUROC)");
  features::OrbExtractor extractor;
  const features::StereoMatcher matcher(sample->cam0, sample->cam1);
  for (auto _ : state) {
    const auto left = extractor.extract(sample->frame.image0);
    const auto right = extractor.extract(sample->frame.image1);
    benchmark::DoNotOptimize(matcher.match(left, right));
  }
}
BENCHMARK(BM_OrbStereoPair)->Unit(benchmark::kMillisecond);

void BM_XFeatExtract(benchmark::State& state) {
  const auto& sample = stereoSample();
  if (!sample) return state.SkipWithError("EuRoC excerpt not found (SUPERDYNA_BENCH_EUROC)");
  const fs::path model =
      fromEnvironmentOr("SUPERDYNA_MODEL_DIR", fs::path(SUPERDYNA_SHARED_DIR) / "models") /
      "xfeat.onnx";
  if (!fs::exists(model)) return state.SkipWithError("xfeat.onnx not found (SUPERDYNA_MODEL_DIR)");
  features::XFeatOptions options;
  options.model = model.string();
  features::XFeatExtractor extractor(options);
  for (auto _ : state)
    benchmark::DoNotOptimize(extractor.extract(sample->frame.image0));
}
BENCHMARK(BM_XFeatExtract)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();

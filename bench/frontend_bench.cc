// Speed of the front end on real 752x480 EuRoC frames (../shared/data/euroc/V1_01_easy_micro, or
// SUPERDYNA_BENCH_EUROC): ORB extraction, ORB extraction + unrectified stereo matching of a pair,
// XFeat extraction (model from $SUPERDYNA_MODEL_DIR or ../shared/models), XFeat extraction + float
// stereo matching of a pair, and SuperPoint-contract extraction with a model composed from
// xfeat.onnx at start-up by scripts/make_superpoint_from_xfeat.py (needs Debian's python3-onnx;
// written to a temporary folder). A benchmark whose data or model is absent reports why and is
// skipped.
//
//   build/bin/superdyna_bench [--benchmark_filter=Orb] [--benchmark_repetitions=5]

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <string>

#include "superdyna/features/alike_extractor.h"
#include "superdyna/features/area_resize.h"
#include "superdyna/features/orb_extractor.h"
#include "superdyna/features/stereo_matcher.h"
#include "superdyna/features/superpoint_extractor.h"
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
  sensors::FrameBundle frame;
  sensors::CameraCalibration cam0, cam1;
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

/// ORB's pyramid (factor 1.2, 8 levels) of a EuRoC image: cv::resize (INTER_AREA) level by level
/// (state.range(0) == 0) or AreaShrinker, the same bytes.
void BM_OrbPyramid(benchmark::State& state) {
  const auto& sample = stereoSample();
  if (!sample) return state.SkipWithError("EuRoC excerpt not found (SUPERDYNA_BENCH_EUROC)");
  const cv::Mat& image = sample->frame.image0;
  features::OrbExtractor extractor;  // its pyramid's level sizes
  extractor.extract(image);
  std::vector<cv::Size> sizes;
  for (const cv::Mat& level : extractor.pyramid())
    sizes.push_back(level.size());
  std::vector<features::AreaShrinker> shrinkers;
  for (std::size_t l = 1; l < sizes.size(); ++l)
    shrinkers.emplace_back(sizes[l - 1], sizes[l]);
  std::vector<cv::Mat> levels(sizes.size());
  levels[0] = image;
  for (auto _ : state) {
    for (std::size_t l = 1; l < sizes.size(); ++l) {
      if (state.range(0) == 0) {
        cv::resize(levels[l - 1], levels[l], sizes[l], 0.0, 0.0, cv::INTER_AREA);
      } else {
        shrinkers[l - 1].apply(levels[l - 1], levels[l]);
      }
    }
    benchmark::DoNotOptimize(levels.back().data);
  }
  state.SetLabel(state.range(0) == 0 ? "cv::resize" : "AreaShrinker");
}
BENCHMARK(BM_OrbPyramid)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

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

fs::path xfeatModel() {
  return fromEnvironmentOr("SUPERDYNA_MODEL_DIR", fs::path(SUPERDYNA_SHARED_DIR) / "models") /
         "xfeat.onnx";
}

/// XFeat options with the model set, or nullopt after marking the benchmark skipped because the
/// EuRoC excerpt or xfeat.onnx is missing.
std::optional<features::XFeatOptions> xfeatOptionsOrSkip(benchmark::State& state) {
  if (!stereoSample()) {
    state.SkipWithError("EuRoC excerpt not found (SUPERDYNA_BENCH_EUROC)");
    return std::nullopt;
  }
  if (!fs::exists(xfeatModel())) {
    state.SkipWithError("xfeat.onnx not found (SUPERDYNA_MODEL_DIR)");
    return std::nullopt;
  }
  features::XFeatOptions options;
  options.model = xfeatModel().string();
  return options;
}

void BM_XFeatExtract(benchmark::State& state) {
  const auto options = xfeatOptionsOrSkip(state);
  if (!options) return;
  const auto& sample = stereoSample();
  features::XFeatExtractor extractor(*options);
  for (auto _ : state)
    benchmark::DoNotOptimize(extractor.extract(sample->frame.image0));
}
BENCHMARK(BM_XFeatExtract)->Unit(benchmark::kMillisecond);

/// One image with ONNX Runtime configured by the arguments (intra-op threads, spinning 0/1):
/// process CPU time (all threads), and the mean network and decoding [ms] per call as counters.
void BM_XFeatExtractRuntime(benchmark::State& state) {
  auto options = xfeatOptionsOrSkip(state);
  if (!options) return;
  const auto& sample = stereoSample();
  options->runtime.intra_op_threads = static_cast<int>(state.range(0));
  options->runtime.allow_spinning = state.range(1) != 0;
  features::XFeatExtractor extractor(*options);
  double network_ms = 0.0, total_ms = 0.0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(extractor.extract(sample->frame.image0));
    network_ms += extractor.lastInferenceMs();
    total_ms += extractor.lastExtractMs();
  }
  const auto runs = static_cast<double>(state.iterations());
  state.counters["network_ms"] = network_ms / runs;
  state.counters["decode_ms"] = (total_ms - network_ms) / runs;
}
BENCHMARK(BM_XFeatExtractRuntime)
    ->ArgsProduct({{1, 2}, {0, 1}})
    ->ArgNames({"threads", "spin"})
    ->MeasureProcessCPUTime()
    ->Unit(benchmark::kMillisecond);

void BM_XFeatStereoPair(benchmark::State& state) {
  auto options = xfeatOptionsOrSkip(state);
  if (!options) return;
  const auto& sample = stereoSample();
  features::XFeatExtractor left(*options), right(*options);
  const features::StereoMatcher matcher(sample->cam0, sample->cam1);
  std::size_t matches = 0;
  for (auto _ : state) {
    const auto stereo =
        matcher.match(left.extract(sample->frame.image0), right.extract(sample->frame.image1));
    matches = stereo.size();
    benchmark::DoNotOptimize(stereo);
  }
  state.counters["stereo_matches"] = static_cast<double>(matches);
}
BENCHMARK(BM_XFeatStereoPair)->Unit(benchmark::kMillisecond);

/// The SuperPoint-contract model composed from xfeat.onnx, made once; nullopt (with the reason)
/// when xfeat.onnx or python3-onnx is missing.
const std::optional<fs::path>& composedSuperPoint(std::string* why) {
  static std::string reason;
  static const std::optional<fs::path> model = []() -> std::optional<fs::path> {
    if (!fs::exists(xfeatModel())) {
      reason = "xfeat.onnx not found (SUPERDYNA_MODEL_DIR)";
      return std::nullopt;
    }
    if (std::system("/usr/bin/python3 -c 'import onnx' >/dev/null 2>&1") != 0) {
      reason = "Debian's python3-onnx is not installed";
      return std::nullopt;
    }
    const fs::path out = fs::temp_directory_path() / "superdyna_bench_superpoint_xfeat.onnx";
    const std::string command = std::string("/usr/bin/python3 ") + SUPERDYNA_SOURCE_DIR +
                                "/scripts/make_superpoint_from_xfeat.py from-xfeat --xfeat " +
                                xfeatModel().string() + " --out " + out.string() + " >/dev/null";
    if (std::system(command.c_str()) != 0) {
      reason = "scripts/make_superpoint_from_xfeat.py failed";
      return std::nullopt;
    }
    return out;
  }();
  *why = reason;
  return model;
}

void BM_SuperPointExtract(benchmark::State& state) {
  const auto& sample = stereoSample();
  if (!sample) return state.SkipWithError("EuRoC excerpt not found (SUPERDYNA_BENCH_EUROC)");
  std::string why;
  const auto& model = composedSuperPoint(&why);
  if (!model) return state.SkipWithError(why.c_str());
  features::SuperPointOptions options;
  options.model = model->string();
  features::SuperPointExtractor extractor(options);
  for (auto _ : state)
    benchmark::DoNotOptimize(extractor.extract(sample->frame.image0));
}
BENCHMARK(BM_SuperPointExtract)->Unit(benchmark::kMillisecond);

/// A shipped model by file name (SUPERDYNA_MODEL_DIR, else ../shared/models).
fs::path sharedModel(const std::string& name) {
  return fromEnvironmentOr("SUPERDYNA_MODEL_DIR", fs::path(SUPERDYNA_SHARED_DIR) / "models") / name;
}

/// SuperPoint-Optimized (3-channel SuperPoint layout) on one EuRoC image, one inference thread.
void BM_SuperPointOptimizedExtract(benchmark::State& state) {
  const auto& sample = stereoSample();
  if (!sample) return state.SkipWithError("EuRoC excerpt not found (SUPERDYNA_BENCH_EUROC)");
  const fs::path model = sharedModel("superpoint_optimized.onnx");
  if (!fs::exists(model)) return state.SkipWithError("superpoint_optimized.onnx not found");
  features::SuperPointOptions options;
  options.model = model.string();
  options.runtime.intra_op_threads = 1;
  options.warmup_size = sample->frame.image0.size();  // the first run grows ONNX Runtime's arena
  features::SuperPointExtractor extractor(options);
  double network_ms = 0.0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(extractor.extract(sample->frame.image0));
    network_ms += extractor.lastInferenceMs();
  }
  state.counters["network_ms"] = network_ms / static_cast<double>(state.iterations());
}
BENCHMARK(BM_SuperPointOptimizedExtract)->Unit(benchmark::kMillisecond);

/// ALIKE variant t / s / n / l (argument 0..3) on one EuRoC image, one inference thread.
void BM_AlikeExtract(benchmark::State& state) {
  const auto& sample = stereoSample();
  if (!sample) return state.SkipWithError("EuRoC excerpt not found (SUPERDYNA_BENCH_EUROC)");
  static const char* const kVariants[] = {"alike-t.onnx", "alike-s.onnx", "alike-n.onnx",
                                          "alike-l.onnx"};
  const fs::path model = sharedModel(kVariants[state.range(0)]);
  if (!fs::exists(model)) return state.SkipWithError("ALIKE model not found");
  features::AlikeOptions options;
  options.model = model.string();
  options.runtime.intra_op_threads = 1;
  options.warmup_size = sample->frame.image0.size();  // the first run grows ONNX Runtime's arena
  features::AlikeExtractor extractor(options);
  double network_ms = 0.0;
  std::size_t keypoints = 0;
  for (auto _ : state) {
    const auto features = extractor.extract(sample->frame.image0);
    keypoints = features.size();
    network_ms += extractor.lastInferenceMs();
  }
  state.counters["network_ms"] = network_ms / static_cast<double>(state.iterations());
  state.counters["keypoints"] = static_cast<double>(keypoints);
  state.SetLabel(kVariants[state.range(0)]);
}
BENCHMARK(BM_AlikeExtract)->DenseRange(0, 3)->ArgName("variant")->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();

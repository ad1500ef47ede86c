// Cost of place recognition (loop::KeyFrameDatabase) against the size of the map: the query of
// one keyframe's place descriptors (loop.database_max_descriptors, 400) in an index of N keyframes,
// for ORB (256-bit binary, Hamming) and float descriptors (XFeat 64-d, SuperPoint 256-d, inner
// product), and the index memory. Descriptors are random (uniform bits; Gaussian unit vectors):
// the exact index costs the same whatever they hold (the graph index about the same). Second
// argument: loop.database_hnsw_search (0 = exact). A keyframe every 0.5 s is 3600 keyframes in a
// 30-minute sequence.
// All keyframes are in the graph index (hold_s 0, settled). BM_AddOrb: the cost of indexing a
// keyframe, add() and settle() into the graph (a graph index links every new descriptor).
// Usage: build/bin/superdyna_loop_bench [benchmark options]

#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <random>
#include <tuple>
#include <utility>
#include <vector>

#include "superdyna/loop/keyframe_database.h"

namespace {

using superdyna::loop::KeyFrameDatabase;

constexpr int kRows = 400;  // place descriptors per keyframe (the default)

cv::Mat randomRows(int type, int cols, std::mt19937& rng) {
  cv::Mat rows(kRows, cols, type);
  if (type == CV_8UC1) {
    std::uniform_int_distribution<int> byte(0, 255);
    for (int r = 0; r < rows.rows; ++r)
      for (int c = 0; c < cols; ++c)
        rows.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(byte(rng));
  } else {
    std::normal_distribution<float> gauss(0.0f, 1.0f);
    for (int r = 0; r < rows.rows; ++r)
      for (int c = 0; c < cols; ++c)
        rows.at<float>(r, c) = gauss(rng);
  }
  return rows;
}

/// A database of `keyframes` keyframes, built once per (type, cols, size, index) and kept.
const KeyFrameDatabase& database(int type, int cols, int keyframes, int hnsw_search) {
  static std::map<std::tuple<int, int, int, int>, std::unique_ptr<KeyFrameDatabase>> built;
  auto& slot = built[{type, cols, keyframes, hnsw_search}];
  if (!slot) {
    superdyna::loop::KeyFrameDatabaseOptions options;
    options.hnsw_search = hnsw_search;
    options.hold_s = 0.0;
    slot = std::make_unique<KeyFrameDatabase>(options);
    std::mt19937 rng(1);
    std::vector<superdyna::map::KeyFrameId> ids;
    for (int k = 0; k < keyframes; ++k) {
      slot->add(k, 0, randomRows(type, cols, rng));
      ids.push_back(k);
    }
    slot->settle(0, ids);
  }
  return *slot;
}

void query(benchmark::State& state, int type, int cols) {
  const int keyframes = static_cast<int>(state.range(0));
  const int hnsw_search = static_cast<int>(state.range(1));
  const KeyFrameDatabase& db = database(type, cols, keyframes, hnsw_search);
  std::mt19937 rng(2);
  const cv::Mat rows = randomRows(type, cols, rng);
  for (auto _ : state)
    benchmark::DoNotOptimize(db.query(rows));
  state.counters["keyframes"] = keyframes;
  state.counters["index_MB"] = static_cast<double>(db.indexBytes()) / 1e6;
}

/// Indexing one keyframe's place descriptors into a database of state.range(0) keyframes (its own
/// database: each iteration adds a keyframe, a few percent of the map over the run).
void add(benchmark::State& state, int type, int cols) {
  const int keyframes = static_cast<int>(state.range(0));
  superdyna::loop::KeyFrameDatabaseOptions options;
  options.hnsw_search = static_cast<int>(state.range(1));
  options.hold_s = 0.0;
  KeyFrameDatabase db(options);
  std::mt19937 rng(3);
  std::vector<superdyna::map::KeyFrameId> ids;
  for (int k = 0; k < keyframes; ++k) {
    db.add(k, 0, randomRows(type, cols, rng));
    ids.push_back(k);
  }
  db.settle(0, ids);
  for (auto _ : state) {
    state.PauseTiming();
    const cv::Mat rows = randomRows(type, cols, rng);
    ids.push_back(static_cast<superdyna::map::KeyFrameId>(ids.size()));
    state.ResumeTiming();
    db.add(ids.back(), 0, rows);
    db.settle(0, ids);
  }
  state.counters["keyframes"] = keyframes;
}

void BM_AddOrb(benchmark::State& state) {
  add(state, CV_8UC1, 32);
}

void BM_QueryOrb(benchmark::State& state) {
  query(state, CV_8UC1, 32);
}
void BM_QueryXFeat(benchmark::State& state) {
  query(state, CV_32FC1, 64);
}
void BM_QuerySuperPoint(benchmark::State& state) {
  query(state, CV_32FC1, 256);
}

BENCHMARK(BM_QueryOrb)
    ->ArgsProduct({{100, 400, 1600, 3600}, {0, 16, 64}})
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_AddOrb)->ArgsProduct({{100, 400, 1600}, {0, 64}})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_QueryXFeat)
    ->ArgsProduct({{100, 400, 1600, 3600}, {0, 16, 64}})
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_QuerySuperPoint)
    ->ArgsProduct({{100, 400, 1600}, {0, 16, 64}})
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();

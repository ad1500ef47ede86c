#!/usr/bin/env bash
# Builds the tests of the concurrent pipeline with ThreadSanitizer and runs them; any data race
# report stops the run with a non-zero exit code.
#
# Usage: scripts/tsan.sh [--quick]
#   --quick  the subset scripts/test.sh (so CI) runs: everything below but the four long SLAM
#            tests (ConcurrentSlam.TracksSyntheticStreetWithinBound, ...RecoversFromLostTracking...,
#            the loop thread's circle and the relocalisation-while-loop-closing test) and the mono
#            run; about 10 min on 2 cores with the build, without it about 25 min.
# Environment: BUILD_DIR (default build-tsan), JOBS (default 2), TSAN_OPTIONS (appended to
#              halt_on_error=1 and the suppressions of scripts/tsan_suppressions.txt: third-party
#              libraries only), SIMULATOR (an uninstrumented `superdyna` to simulate the test
#              sequence with, e.g. build/bin/superdyna: about 10x faster than the instrumented one).
#
# What runs: the bounded queue and task thread (core_test), the map's update transaction and
# concurrent observation changes (map_test), a local BA against a reader under the map's read lock
# and the global BA solved in its own thread, applied or dropped (mapping_test), the mapping
# worker, the concurrent pipeline's error paths and its segmentation thread started a frame ahead
# with the dataset segmenter (system_test); then
# `superdyna run` in the concurrent pipeline - stereo-inertial (front-end thread, tracking, local
# mapping thread, loop closing thread), mono-inertial and mono (the tracker waits for the mapping
# thread at keyframes and for the inertial initialisation) - on a 7 s sequence simulated once into
# BUILD_DIR (with the MH_03 motion from ../shared when present). Without --quick also the
# concurrent stereo-inertial SLAM tests (ConcurrentSlam.*), relocalisation querying the loop
# closer's database while the loop thread adds to it, and a loop found in the loop thread and
# applied in the mapping thread (mono-inertial: with its global BA in its own thread), and a map
# merge found in the loop thread and applied in the mapping thread. Tests that run learned models are left out: ONNX Runtime is not
# instrumented, so its threads would give false reports.
set -euo pipefail

quick=0
case "${1:-}" in
  --quick) quick=1 ;;
  "") ;;
  *) echo "usage: scripts/tsan.sh [--quick]" >&2; exit 2 ;;
esac
repo_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${BUILD_DIR:-"$repo_dir/build-tsan"}
jobs=${JOBS:-2}

# -O1 with line tables only: half the build time of RelWithDebInfo, and reports still name the
# file and line of each access.
cmake -S "$repo_dir" -B "$build_dir" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_CXX_FLAGS_RELEASE="-O1 -g1 -DNDEBUG" -DCMAKE_CXX_FLAGS=-fsanitize=thread \
  -DCMAKE_EXE_LINKER_FLAGS=-fsanitize=thread -DSUPERDYNA_WERROR=ON >/dev/null
nice -n 10 cmake --build "$build_dir" -j "$jobs" \
  --target core_test map_test mapping_test system_test superdyna

export TSAN_OPTIONS="halt_on_error=1 suppressions=$repo_dir/scripts/tsan_suppressions.txt ${TSAN_OPTIONS:-}"
run() {
  local binary=$1 filter=$2
  echo "[tsan] $binary --gtest_filter=$filter"
  nice -n 10 "$build_dir/bin/$binary" --gtest_filter="$filter" --gtest_brief=1
}
run core_test 'BoundedQueue.*:TaskThread.*'
run map_test 'MapUpdate.*:MapTest.Concurrent*'
run mapping_test 'BundleAdjustmentTest.AReaderUnderTheReadLock*:LocalMapper.*GlobalBa*'
if [ "$quick" = 1 ]; then
  run system_test 'MappingWorker.*:ConcurrentSlam.A*Error*:SystemSegmenter.SegmentingAFrameAhead*'
else
  run system_test 'MappingWorker.*:ConcurrentSlam.*:Relocalisation.PlaceRecognitionWorksWhile*:LoopClosing.*Concurrent*:MapMerging.*Concurrent*:SystemSegmenter.SegmentingAFrameAhead*'
fi

sequence="$build_dir/tsan_sequence"
if [ ! -f "$sequence/mav0/imu0/data.csv" ]; then
  motion=()
  trajectory="${SUPERDYNA_SHARED_DIR:-$repo_dir/../shared}/data/trajectories/euroc/MH_03_medium.txt"
  [ -f "$trajectory" ] && motion=(--trajectory "$trajectory" --start 15)
  nice -n 10 "${SIMULATOR:-$build_dir/bin/superdyna}" simulate --out "$sequence" --scene indoor \
    --dynamic none --duration 7 --seed 3 "${motion[@]}" --overwrite
fi
modes=(stereo-inertial mono-inertial mono)
[ "$quick" = 1 ] && modes=(stereo-inertial mono-inertial)
for mode in "${modes[@]}"; do
  echo "[tsan] superdyna run --mode $mode (concurrent)"
  nice -n 10 "$build_dir/bin/superdyna" run --dataset euroc --path "$sequence" --mode "$mode" \
    --config "$repo_dir/configs/euroc_${mode/-/_}.yaml" --output "$build_dir/tsan_$mode.txt" |
    grep -E "frames in|ATE"
done
echo "[tsan] no data race reported"

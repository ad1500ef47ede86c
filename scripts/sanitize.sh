#!/usr/bin/env bash
# Builds the given test binaries with AddressSanitizer + UndefinedBehaviorSanitizer into
# build-asan/ and runs them (optionally filtered); any report stops the run with a non-zero exit
# code. The instrumented build is slow on 2 cores: build only the binaries you need, and build
# everything at most once in a while.
#
# Usage: scripts/sanitize.sh BINARY[:GTEST_FILTER] [BINARY[:GTEST_FILTER]...]
#        scripts/sanitize.sh --all
#   e.g. scripts/sanitize.sh io_test tracker_test:'ImuGap*:ImuSampleBuffer*' core_test:'AtomicFile*'
#   The name `superdyna` builds the command line tool only (for CLI tests run by hand).
#   --all: the whole suite - every test and the command line tool, then ctest (all but the
#          clang-format check); about 45 min to build and 75 min to run on 2 cores. gcc, as in the
#          normal build.
# Environment: BUILD_DIR (default build-asan), JOBS (default 2), ASAN_OPTIONS / UBSAN_OPTIONS
#              (appended to the defaults below).
set -euo pipefail
[ $# -ge 1 ] || { sed -n '2,16p' "$0"; exit 2; }

repo_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${BUILD_DIR:-"$repo_dir/build-asan"}
jobs=${JOBS:-2}
# Eigen takes malloc as 16-byte aligned on glibc except under AddressSanitizer, where it pads and
# frees its own way; an Eigen matrix that the uninstrumented Ceres allocated and our code frees
# (ceres::GradientChecker::ProbeResults) was then freed wrongly (heap-buffer-overflow in
# handmade_aligned_free). ASan's malloc is 16-byte aligned on x86-64: keep Eigen's normal allocator.
flags="-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined"
flags+=" -DEIGEN_MALLOC_ALREADY_ALIGNED=1"

targets=()
for spec in "$@"; do targets+=("${spec%%:*}"); done

mkdir -p "$build_dir/.deps"
[ -e "$repo_dir/.deps/onnxruntime" ] && ln -sfn "$(readlink -f "$repo_dir/.deps/onnxruntime")" \
  "$build_dir/.deps/onnxruntime"
cmake -S "$repo_dir" -B "$build_dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" \
  -DCMAKE_SHARED_LINKER_FLAGS="-fsanitize=address,undefined" -DSUPERDYNA_WERROR=ON \
  -DSUPERDYNA_BUILD_BENCH=OFF >/dev/null

export ASAN_OPTIONS="halt_on_error=1 detect_leaks=1 ${ASAN_OPTIONS:-}"
export UBSAN_OPTIONS="halt_on_error=1 print_stacktrace=1 ${UBSAN_OPTIONS:-}"
# ONNX Runtime is not instrumented: the few blocks it keeps until exit are not ours to report.
export LSAN_OPTIONS="suppressions=$repo_dir/scripts/lsan_suppressions.txt ${LSAN_OPTIONS:-}"
if [ "$1" = --all ]; then
  nice -n 10 cmake --build "$build_dir" -j "$jobs"
  # A sanitizer report fails the reporting process, so its test.
  nice -n 10 ctest --test-dir "$build_dir" --output-on-failure -j "$jobs" --timeout 3600 \
    -E '^clang_format_check$'
  echo "[asan+ubsan] whole suite: no report"
  exit 0
fi
nice -n 10 cmake --build "$build_dir" -j "$jobs" --target "${targets[@]}"
for spec in "$@"; do
  binary=${spec%%:*}
  [ "$binary" = superdyna ] && continue
  filter='*'
  [ "$spec" != "$binary" ] && filter=${spec#*:}
  echo "[asan+ubsan] $binary --gtest_filter=$filter"
  nice -n 10 "$build_dir/bin/$binary" --gtest_filter="$filter" --gtest_brief=1
done
echo "[asan+ubsan] no report"

#!/usr/bin/env bash
# The fast tests of the parsers and containers under AddressSanitizer + UndefinedBehaviorSanitizer,
# built in the fuzzers' clang build (build-fuzz/, configured by bench/fuzz.sh): its libraries are
# already instrumented, so only the tests themselves compile. scripts/test.sh runs it after the
# fuzzing; any report fails the run. (scripts/sanitize.sh builds any test binary with gcc's
# sanitizers; scripts/tsan.sh the concurrent pipeline with ThreadSanitizer.)
# Usage: scripts/asan_tests.sh [BINARY[:GTEST_FILTER]...]
#   default: io_test core_test map_test map_file_test
# Environment: BUILD_DIR (default build-fuzz), JOBS (default 2).
set -euo pipefail
repo_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${BUILD_DIR:-"$repo_dir/build-fuzz"}
jobs=${JOBS:-2}
specs=("$@")
[ ${#specs[@]} -gt 0 ] || specs=(io_test core_test map_test map_file_test)
if [ ! -f "$build_dir/CMakeCache.txt" ]; then
  echo "error: no instrumented build in $build_dir: run bench/fuzz.sh first (it configures it)" >&2
  exit 2
fi
targets=()
for spec in "${specs[@]}"; do targets+=("${spec%%:*}"); done
# The fuzz build is configured without tests; turning them on changes no compile flag.
cmake -S "$repo_dir" -B "$build_dir" -DSUPERDYNA_BUILD_TESTS=ON >/dev/null
nice -n 10 cmake --build "$build_dir" -j "$jobs" --target "${targets[@]}"

export ASAN_OPTIONS="halt_on_error=1 detect_leaks=1 ${ASAN_OPTIONS:-}"
export LSAN_OPTIONS="suppressions=$repo_dir/scripts/lsan_suppressions.txt ${LSAN_OPTIONS:-}"
export UBSAN_OPTIONS="halt_on_error=1 print_stacktrace=1 ${UBSAN_OPTIONS:-}"
for spec in "${specs[@]}"; do
  binary=${spec%%:*}
  filter='*'
  [ "$spec" != "$binary" ] && filter=${spec#*:}
  echo "[asan+ubsan] $binary --gtest_filter=$filter"
  nice -n 10 "$build_dir/bin/$binary" --gtest_filter="$filter" --gtest_brief=1
done
echo "[asan+ubsan] no report"

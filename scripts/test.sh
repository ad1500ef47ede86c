#!/usr/bin/env bash
# Quick start, step 2: install dependencies, build, run the whole test suite (then brief fuzzing,
# ASan/UBSan and ThreadSanitizer runs: see below).
# Tests that need ../shared (real data and models beside the checkout) skip with a message when it
# is absent (fail with SUPERDYNA_REQUIRE_SHARED=1, as in CI); point SUPERDYNA_SHARED_DIR elsewhere to
# use another copy.
set -euo pipefail
repo_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${BUILD_DIR:-"$repo_dir/build"}
# A fresh build treats warnings as errors (as CI does, on a clean checkout); a build the quick
# start already configured keeps its setting instead of recompiling everything with -Werror.
if [ -z "${SUPERDYNA_WERROR:-}" ] && [ ! -f "$build_dir/CMakeCache.txt" ]; then
  export SUPERDYNA_WERROR=ON
fi
"$repo_dir/scripts/setup.sh"
ctest --test-dir "$build_dir" --output-on-failure -j "${JOBS:-$(nproc)}" --timeout 1200
# Brief fuzzing of the io and map parsers (bench/fuzz.sh: a clang ASan/UBSan build of those
# modules only, in build-fuzz/), then their unit tests in that build (scripts/asan_tests.sh):
# SUPERDYNA_FUZZ_SECONDS per target, 0 skips both.
fuzz_seconds=${SUPERDYNA_FUZZ_SECONDS:-15}
if [ "$fuzz_seconds" != 0 ]; then
  JOBS=${JOBS:-$(nproc)} "$repo_dir/bench/fuzz.sh" "$fuzz_seconds" euroc_csv euroc_sensor_yaml kitti trajectory \
    instance_mask map_file
  # The parser and container tests under ASan + UBSan, in that instrumented build.
  JOBS=${JOBS:-$(nproc)} "$repo_dir/scripts/asan_tests.sh"
fi
# The concurrent pipeline under ThreadSanitizer (scripts/tsan.sh --quick: an instrumented build of
# the libraries and the concurrency tests in build-tsan/, their tests and concurrent `superdyna
# run`s on a 7 s sequence simulated by the normal build): SUPERDYNA_TSAN=0 skips it.
if [ "${SUPERDYNA_TSAN:-1}" != 0 ]; then
  JOBS=${JOBS:-$(nproc)} SIMULATOR="$build_dir/bin/superdyna" "$repo_dir/scripts/tsan.sh" --quick
fi

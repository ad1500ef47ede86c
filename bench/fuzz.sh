#!/usr/bin/env bash
# Runs the libFuzzer targets of the parsers (fuzz/): configures and builds the clang build
# (SUPERDYNA_FUZZ=ON: ASan + UBSan + coverage) into build-fuzz/ when needed, then runs each target
# for the given time or number of executions, starting from its seeds (fuzz/corpus/<target>) and
# the inputs earlier runs kept (build-fuzz/corpus/<target>). Prints executions and the result per
# target; a crash, sanitizer report, leak or hang fails the run (exit 1) and leaves the input in
# build-fuzz/artifacts/.
#
# Usage: bench/fuzz.sh SECONDS|-runs=N [TARGET...]
#   e.g. bench/fuzz.sh 60                 every default target for 60 s each
#        bench/fuzz.sh -runs=1000000 kitti
# Targets: euroc_csv euroc_sensor_yaml kitti trajectory instance_mask map_file (the io and map
# parsers, also run by scripts/test.sh), segmentation (links semantics: features and ONNX
# Runtime), options (links the whole SLAM system: slow to build, only when named).
# Environment: BUILD_DIR (default build-fuzz), JOBS (default 1), FUZZ_SEED (default 1; 0 = random),
#              FUZZ_TIMEOUT (seconds per input counted as a hang, default 10), FUZZ_MAX_SECONDS
#              (with -runs=N: stop a target after this long even if it has not made N runs).
set -euo pipefail
[ $# -ge 1 ] || { sed -n '2,18p' "$0"; exit 2; }

repo_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${BUILD_DIR:-"$repo_dir/build-fuzz"}
jobs=${JOBS:-1}
limit=$1
shift
case "$limit" in
  -runs=*) limit_flags=("$limit")
    [ -z "${FUZZ_MAX_SECONDS:-}" ] || limit_flags+=("-max_total_time=$FUZZ_MAX_SECONDS") ;;
  *[!0-9]* | "") echo "error: '$limit' is neither SECONDS nor -runs=N" >&2; exit 2 ;;
  *) limit_flags=("-max_total_time=$limit") ;;
esac
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(euroc_csv euroc_sensor_yaml kitti trajectory instance_mask
                                     map_file segmentation)

configure() {
  mkdir -p "$build_dir/.deps"
  [ -e "$repo_dir/.deps/onnxruntime" ] && ln -sfn "$(readlink -f "$repo_dir/.deps/onnxruntime")" \
    "$build_dir/.deps/onnxruntime"
  cmake -S "$repo_dir" -B "$build_dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_COMPILER=clang++ -DSUPERDYNA_FUZZ=ON -DSUPERDYNA_BUILD_TESTS=OFF \
    -DSUPERDYNA_BUILD_BENCH=OFF -DSUPERDYNA_WERROR=ON >/dev/null
}

build() {
  local names=() target
  for target in "${targets[@]}"; do names+=("superdyna_fuzz_$target"); done
  nice -n 10 cmake --build "$build_dir" -j "$jobs" --target "${names[@]}"
}

# The parsers under test write their files here: memory, not disk, when /dev/shm is usable.
scratch_dir() {
  if [ -d /dev/shm ] && [ -w /dev/shm ]; then echo /dev/shm; else echo "${TMPDIR:-/tmp}"; fi
}

# Runs one target; prints "<target>: <executions> executions in <s> s (<rate>/s): <result>".
run_target() {
  local target=$1 corpus="$build_dir/corpus/$1" log="$build_dir/logs/$1.log"
  mkdir -p "$corpus" "$build_dir/artifacts" "$build_dir/logs"
  local start=$SECONDS status=0
  TMPDIR=$(scratch_dir) nice -n 10 "$build_dir/bin/superdyna_fuzz_$target" "${limit_flags[@]}" \
    -seed="${FUZZ_SEED:-1}" -timeout="${FUZZ_TIMEOUT:-10}" -print_final_stats=1 \
    -artifact_prefix="$build_dir/artifacts/$target-" "$corpus" "$repo_dir/fuzz/corpus/$target" \
    >"$log" 2>&1 || status=$?
  local executions
  executions=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  local seconds=$((SECONDS - start))
  local rate=$((${executions:-0} / (seconds > 0 ? seconds : 1)))
  if [ "$status" -eq 0 ]; then
    echo "$target: ${executions:-?} executions in $seconds s ($rate/s): ok"
  else
    echo "$target: ${executions:-?} executions in $seconds s ($rate/s): FAILED (exit $status)"
    grep -E "ERROR|runtime error|SUMMARY|Test unit written" "$log" | head -5 | sed 's/^/  /'
    echo "  full log: $log"
  fi
  return "$status"
}

[ -f "$build_dir/CMakeCache.txt" ] || configure
build
failed=0
for target in "${targets[@]}"; do
  run_target "$target" || failed=1
done
exit "$failed"

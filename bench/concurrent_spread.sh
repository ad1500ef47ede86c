#!/usr/bin/env bash
# Run-to-run spread of the concurrent pipeline: runs `superdyna run` RUNS times on one EuRoC-layout
# sequence (concurrent mode, the default) and reports the ATE of each run plus median and
# mean ± 95% CI (superdyna eval's N-run statistics), for the frame and the keyframe trajectories.
# Usage: bench/concurrent_spread.sh SEQ [RUNS=5] [MODE=stereo-inertial] [CONFIG] [OUT_DIR]
#   SEQ     sequence folder holding mav0/ (with state_groundtruth_estimate0/data.csv)
#   CONFIG  default configs/euroc_stereo_inertial.yaml or configs/euroc_stereo.yaml by MODE
#   OUT_DIR trajectories and logs (default: a new folder under ${TMPDIR:-/tmp})
# Environment: SUPERDYNA (the binary, default build/bin/superdyna), RUN_ARGS (extra run options).
set -euo pipefail
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
superdyna=${SUPERDYNA:-$repo/build/bin/superdyna}
if [ $# -lt 1 ]; then
  sed -n '2,9p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
  exit 1
fi
seq=$1
runs=${2:-5}
mode=${3:-stereo-inertial}
case "$mode" in
  stereo-inertial) default_config=$repo/configs/euroc_stereo_inertial.yaml ;;
  *) default_config=$repo/configs/euroc_stereo.yaml ;;
esac
config=${4:-$default_config}
out=${5:-$(mktemp -d "${TMPDIR:-/tmp}/superdyna_spread.XXXXXX")}
gt=$seq/mav0/state_groundtruth_estimate0/data.csv
[ -f "$gt" ] || { echo "no ground truth at $gt" >&2; exit 2; }
mkdir -p "$out"
echo "sequence $seq, mode $mode, config $config, $runs concurrent runs; files in $out"
frames=() keyframes=()
for i in $(seq 1 "$runs"); do
  log=$out/run_$i.log
  # shellcheck disable=SC2086
  "$superdyna" run --dataset euroc --path "$seq" --mode "$mode" --config "$config" \
    --output "$out/run_$i.txt" --keyframes "$out/run_${i}_keyframes.txt" ${RUN_ARGS:-} >"$log" 2>&1 ||
    { echo "run $i failed, see $log" >&2; tail -5 "$log" >&2; exit 1; }
  echo "run $i: $(grep -E '^[0-9]+ frames in' "$log" | sed 's/; wrote.*//') | $(grep -E '^ATE' "$log")"
  frames+=(--est "$out/run_$i.txt")
  keyframes+=(--est "$out/run_${i}_keyframes.txt")
done
echo
echo "frame trajectories (every frame, pose as tracked):"
"$superdyna" eval --gt "$gt" "${frames[@]}" --json "$out/frames.json"
echo
echo "keyframe trajectories (poses after local BA):"
"$superdyna" eval --gt "$gt" "${keyframes[@]}" --json "$out/keyframes.json"

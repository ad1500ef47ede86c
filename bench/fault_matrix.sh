#!/usr/bin/env bash
# Sensor faults against the whole pipeline (issue 17): simulates one street sequence on the real
# EuRoC V2_02 motion clean, with each fault of `superdyna simulate` alone, and with all of them
# together; runs stereo-inertial and mono-inertial SLAM (`--deterministic`, shipped configs) on
# each and tabulates whether the run finished, its lost frames, map resets, relocalisations and
# ATE next to the clean run's. A run that crashes or exceeds TIMEOUT seconds is reported as such.
# Usage: bench/fault_matrix.sh OUT_DIR [DURATION_S]
#   OUT_DIR     sequences (kept between runs: delete to regenerate), trajectories, logs, results.md
#   DURATION_S  sequence length, default 20 (the faults sit between 6 s and 14 s)
# Environment: SHARED (default ../shared beside the repository), BUILD (default build), TIMEOUT
# (default 900 s per run), SEED (default 31), ONLY (names of the faults to run, e.g. "clean all";
# default every one). Takes about 35 minutes on 2 cores with 20 s.
set -euo pipefail
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
if [ $# -lt 1 ]; then
  sed -n '2,11p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
  exit 1
fi
out=$(mkdir -p "$1" && cd "$1" && pwd)
duration=${2:-20}
shared=${SHARED:-$repo/../shared}
build=${BUILD:-$repo/build}
timeout_s=${TIMEOUT:-900}
seed=${SEED:-31}
superdyna=$build/bin/superdyna
motion=$shared/data/trajectories/euroc/V2_02_medium.txt
[ -x "$superdyna" ] || { echo "$superdyna not built (scripts/setup.sh builds it)" >&2; exit 2; }
[ -f "$motion" ] || { echo "no $motion (set SHARED)" >&2; exit 2; }

# name | fault options of `superdyna simulate`
faults=(
  "clean|"
  "dropped_frames|--drop-frames 0.05"
  "imu_gap_1s|--imu-gap 8:9"
  "imu_nan|--imu-nan 10:10.5"
  "black_2s|--black-frames 9:11"
  "overexposed_1s|--overexposed-frames 12:13"
  "missing_cam1_2s|--missing-cam1 6:8"
  "time_offset_5ms|--time-offset 0.005"
  "repeated_timestamps_1s|--repeat-timestamps 7:8"
  "swapped_timestamps_1s|--swap-timestamps 11:12"
  "imu_saturated_0.2s|--imu-saturate 13:13.2"
  "all|--drop-frames 0.05 --imu-gap 8:9 --imu-nan 10:10.5 --black-frames 9:11 --overexposed-frames 12:13 --missing-cam1 6:8 --time-offset 0.005 --repeat-timestamps 7:8 --swap-timestamps 11:12 --imu-saturate 13:13.2"
)
if [ -n "${ONLY:-}" ]; then
  selected=()
  for entry in "${faults[@]}"; do
    [[ " $ONLY " == *" ${entry%%|*} "* ]] && selected+=("$entry")
  done
  [ ${#selected[@]} -gt 0 ] || { echo "ONLY=$ONLY names no fault of this script" >&2; exit 2; }
  faults=("${selected[@]}")
fi
modes=("stereo-inertial|euroc_stereo_inertial.yaml" "mono-inertial|euroc_mono_inertial.yaml")

for entry in "${faults[@]}"; do
  name=${entry%%|*}
  options=${entry#*|}
  sequence=$out/$name
  [ -d "$sequence/mav0" ] && continue
  echo "[fault_matrix] simulating $name"
  # shellcheck disable=SC2086  # the fault options are words
  "$superdyna" simulate --out "$sequence" --scene street --dynamic none --duration "$duration" \
    --seed "$seed" --trajectory "$motion" --start 5 $options >"$out/$name.simulate.log" 2>&1
done

results=$out/results.md
{
  echo "| fault | mode | finished | lost frames | map resets | relocalisations | ATE [m] | clean ATE [m] |"
  echo "| --- | --- | --- | --- | --- | --- | --- | --- |"
} >"$results"
for mode_entry in "${modes[@]}"; do
  mode=${mode_entry%%|*}
  config=$repo/configs/${mode_entry#*|}
  clean_ate=""
  for entry in "${faults[@]}"; do
    name=${entry%%|*}
    log=$out/$name.$mode.log
    echo "[fault_matrix] $mode on $name"
    status=0
    timeout "$timeout_s" "$superdyna" run --dataset euroc --path "$out/$name" --mode "$mode" \
      --config "$config" --deterministic --output "$out/$name.$mode.txt" >"$log" 2>&1 || status=$?
    finished=yes
    [ "$status" -eq 0 ] || finished="no (exit $status)"
    [ "$status" -eq 124 ] && finished="no (over ${timeout_s} s)"
    summary=$(grep -E '^[0-9]+ frames in' "$log" || true)
    lost=$(sed -nE 's/.*lost frames ([0-9]+).*/\1/p' <<<"$summary")
    resets=$(sed -nE 's/.*map resets ([0-9]+).*/\1/p' <<<"$summary")
    relocalisations=$(sed -nE 's/.*relocalisations ([0-9]+).*/\1/p' <<<"$summary")
    ate=$(grep -E '^ATE \(SE\(3\) aligned\)' "$log" | sed -nE 's/.*rmse ([0-9.]+) m.*/\1/p' || true)
    [ "$name" = clean ] && clean_ate=$ate
    echo "| $name | $mode | $finished | ${lost:--} | ${resets:--} | ${relocalisations:--} | ${ate:--} | ${clean_ate:--} |" >>"$results"
  done
done
cat "$results"

#!/usr/bin/env bash
# Memory and time per frame over a long run: simulates one 210 s lap of the indoor scene's
# procedural flight (it repeats after 210 s: bench/repeat_sequence.py), repeats it LAPS times
# (default 9: 31.5 min, 37 800 frames at 20 Hz) and runs `superdyna run` over it, reading the
# progress lines (frames, FPS, keyframes, map points, resident memory and the allocator's heap in
# use and freed-but-kept, about once a second). Prints per sequence minute the frame rate, map
# size, RSS and heap, and the RSS growth after the first 5 minutes (max RSS after minute 5 over
# the RSS at minute 5); fails (exit 1) when it is MAX_GROWTH percent (default 20) or more.
#
# Usage: bench/memory_soak.sh [--report] OUT_DIR [LAPS=9]
#   OUT_DIR   the lap (OUT_DIR/lap, simulated once and reused), the repeated sequence
#             (OUT_DIR/soak, symbolic links to the lap's images), trajectory and run log
#   --report  only tabulate the run.log of an earlier run in OUT_DIR
# Environment: SUPERDYNA (binary, default build/bin/superdyna), MODE (default stereo-inertial),
#   CONFIG (default configs/euroc_<MODE>.yaml), RUN_ARGS (extra run options, e.g.
#   --deterministic), MAX_GROWTH (percent).
set -euo pipefail
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
superdyna=${SUPERDYNA:-$repo/build/bin/superdyna}
if [ $# -lt 1 ]; then
  sed -n '2,16p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
  exit 2
fi
report_only=0
[ "$1" = --report ] && { report_only=1; shift; }
out=$1
laps=${2:-9}
mode=${MODE:-stereo-inertial}
config=${CONFIG:-$repo/configs/euroc_${mode/-/_}.yaml}
max_growth=${MAX_GROWTH:-20}
lap_s=210
mkdir -p "$out"
simulate_lap() {
  [ -f "$out/lap/mav0/state_groundtruth_estimate0/data.csv" ] && return
  echo "simulating one ${lap_s} s lap into $out/lap (about 10 min on 2 cores)"
  "$superdyna" simulate --out "$out/lap" --overwrite --scene indoor --dynamic none \
    --duration "$lap_s" --seed 11 >"$out/simulate.log" 2>&1 ||
    { tail -5 "$out/simulate.log" >&2; exit 1; }
}

run_laps() {
  rm -rf "$out/soak"
  python3 "$repo/bench/repeat_sequence.py" "$out/lap" "$out/soak" "$lap_s" "$laps"
  echo "running $mode ($config) over $laps laps; progress in $out/run.log"
  # shellcheck disable=SC2086
  "$superdyna" run --dataset euroc --path "$out/soak" --mode "$mode" --config "$config" \
    --output "$out/trajectory.txt" ${RUN_ARGS:-} >"$out/run.log" 2>&1 ||
    { tail -5 "$out/run.log" >&2; exit 1; }
}

if [ "$report_only" = 0 ]; then
  simulate_lap
  run_laps
fi
frames_per_lap=$(($(wc -l <"$out/lap/mav0/cam0/data.csv") - 2))
grep -E '^[0-9]+ frames in|^ATE \(SE' "$out/run.log" || true

# Progress lines: "frame N/T  F FPS (now R)  STATE  keyframes K  points P  RSS M MB".
awk -v rate="$frames_per_lap" -v lap="$lap_s" -v max_growth="$max_growth" '
  /^frame +[0-9]+\// && / RSS [0-9]+ MB/ {
    split($2, f, "/"); frame = f[1]
    for (i = 1; i <= NF; i++) {
      if ($i == "(now") { now = $(i + 1); sub(/\)/, "", now) }
      if ($i == "keyframes") kf = $(i + 1)
      if ($i == "points") pts = $(i + 1)
      if ($i == "RSS") rss = $(i + 1)
      if ($i == "heap") heap = $(i + 1)
      if ($i == "(free") { heap_free = $(i + 1); sub(/\)/, "", heap_free) }
    }
    minute = int(frame / (rate / lap) / 60)
    n[minute]++; fps[minute] += now; last_kf[minute] = kf; last_pts[minute] = pts
    if (rss > max_rss[minute]) max_rss[minute] = rss
    last_heap[minute] = heap; last_free[minute] = heap_free
    if (minute >= 5 && !(5 in rss_at)) rss_at[5] = rss
    if (minute >= 5 && rss > peak_after) peak_after = rss
    if (minute > last_minute) last_minute = minute
  }
  END {
    printf "| minute | FPS | ms per frame | keyframes | map points | RSS max [MB] | heap in use [MB] | heap free [MB] |\n|---|---|---|---|---|---|---|---|\n"
    for (m = 0; m <= last_minute; m++) {
      if (!(m in n)) continue
      mean = fps[m] / n[m]
      printf "| %d | %.1f | %.1f | %d | %d | %d | %s | %s |\n", m, mean, (mean > 0 ? 1000 / mean : 0),
        last_kf[m], last_pts[m], max_rss[m], last_heap[m], last_free[m]
    }
    if (!(5 in rss_at)) { print "the run is shorter than 5 minutes of sequence: no growth to report"; exit 1 }
    growth = 100 * (peak_after - rss_at[5]) / rss_at[5]
    printf "RSS at minute 5: %d MB, highest after: %d MB, growth %.1f %% (limit %d %%)\n",
      rss_at[5], peak_after, growth, max_growth
    exit (growth >= max_growth ? 1 : 0)
  }' "$out/run.log"

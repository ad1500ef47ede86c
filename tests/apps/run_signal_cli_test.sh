#!/usr/bin/env bash
# End-to-end checks of `superdyna run`'s outputs under faults:
#  1. SIGINT halfway through a sequence: the run stops reading, finishes the frames in flight,
#     writes the trajectory and keyframes of the frames so far, says so and exits 130; no
#     temporary file is left beside the outputs;
#  2. an output path equal to the --config file read is refused and the file left intact;
#  3. a simulated sequence with dropped frames, a NaN IMU stretch and an IMU gap runs to the end
#     stereo-inertially, reporting each fault.
# Usage: run_signal_cli_test.sh SUPERDYNA
set -euo pipefail
superdyna=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

"$superdyna" simulate --out "$work/seq" --scene street --dynamic none --duration 6 --seed 5 \
  --landmarks 0 --drop-frames 17,18,60 --imu-nan 2.0:2.2 --imu-gap 3.0:3.5 >/dev/null 2>&1
frames=$(grep -vc '^#' "$work/seq/mav0/cam0/data.csv")
[ "$frames" -eq 118 ] || { echo "expected 118 frames after dropping 3 of 121, found $frames"; exit 1; }

echo "-- 1. SIGINT halfway"
mkdir -p "$work/out"
"$superdyna" run --path "$work/seq" --mode stereo --deterministic --output "$work/out/traj.tum" \
  >"$work/run.log" 2>&1 &
pid=$!
for _ in $(seq 1 600); do  # the first progress line comes after about 1 s of tracking
  grep -q '^frame ' "$work/run.log" && break
  sleep 0.1
done
kill -INT "$pid"
code=0
wait "$pid" || code=$?
cat "$work/run.log" | grep -v '^  ' || true
[ "$code" -eq 130 ] || { echo "expected exit code 130 after SIGINT, got $code"; exit 1; }
grep -q '^stopped by SIGINT after [0-9]* of 118 frames' "$work/run.log" ||
  { echo "no 'stopped by SIGINT' line"; exit 1; }
poses=$(grep -vc '^#' "$work/out/traj.tum")
[ "$poses" -gt 0 ] && [ "$poses" -lt 118 ] ||
  { echo "expected a partial trajectory, found $poses poses"; exit 1; }
# Every row is a whole pose: time and 7 numbers.
awk '!/^#/ && NF != 8 { exit 1 }' "$work/out/traj.tum" || { echo "a truncated pose row"; exit 1; }
[ -s "$work/out/traj_keyframes.tum" ] || { echo "no keyframe trajectory"; exit 1; }
if ls "$work/out" | grep -q '\.tmp-'; then echo "a temporary file was left"; exit 1; fi
echo "stopped with $poses of 118 poses written"

echo "-- 2. output onto the --config file"
printf 'tracker:\n  imu_max_gap_s: 0.2\n' >"$work/options.yaml"
cp "$work/options.yaml" "$work/options.orig"
if "$superdyna" run --path "$work/seq" --config "$work/options.yaml" \
  --output "$work/options.yaml" >"$work/refused.log" 2>&1; then
  echo "writing the trajectory over --config was not refused"; exit 1
fi
grep -q "is an input file; refusing to overwrite it" "$work/refused.log" ||
  { cat "$work/refused.log"; echo "no refusal message"; exit 1; }
cmp -s "$work/options.yaml" "$work/options.orig" || { echo "--config was changed"; exit 1; }

echo "-- 3. faults reported, run finished"
"$superdyna" run --path "$work/seq" --mode stereo-inertial --deterministic \
  --output "$work/out/vi.tum" >"$work/vi.log" 2>&1 || { cat "$work/vi.log"; exit 1; }
grep -E '^warning|^ATE|frames in' "$work/vi.log"
grep -q 'cam0/data.csv: about 3 dropped frame(s) in 2 time step(s)' "$work/vi.log" ||
  { echo "dropped frames not reported"; exit 1; }
grep -qE 'imu0/data.csv: (39|40|41) row\(s\) with nan or inf values skipped \(lines [0-9]+-[0-9]+\)' "$work/vi.log" ||
  { echo "NaN IMU rows not reported"; exit 1; }
[ "$(grep -c '^warning: IMU gap of' "$work/vi.log")" -eq 2 ] ||
  { echo "expected the NaN stretch and the gap as two IMU gaps"; exit 1; }
[ "$(grep -vc '^#' "$work/out/vi.tum")" -eq 118 ] || { echo "not every frame has a pose"; exit 1; }
echo "all checks passed"

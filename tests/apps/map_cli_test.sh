#!/usr/bin/env bash
# End-to-end checks of map files, a second sequence in the same world and borrowed alignments:
#  1. simulate --world-of: a second sequence (another part of the flight, another seed) rebuilds
#     the first one's static world (same fingerprint); a contradicting --scene, background
#     contrast or texture variety, or a damaged world_source value, is refused;
#  2. run --save-map writes a map; the map options' wrong combinations are refused with a message
#     (exit 2): --localization-only without --load-map, --load-map without --localization-only,
#     --save-map onto the --load-map file, a truncated map file, a map of another sensor mode;
#  3. run --load-map --localization-only tracks the second sequence; saving its (unchanged) map
#     gives the loaded file byte for byte;
#  4. eval --alignment (a report's alignment) and --alignment-from/--alignment-gt (another run's)
#     give the same ATE of the second run.
# Usage: map_cli_test.sh SUPERDYNA
set -euo pipefail
superdyna=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

expect_refusal() {  # FRAGMENT COMMAND...: exit code 2 and FRAGMENT in the output
  local fragment=$1
  shift
  local code=0
  "$@" >"$work/refusal.log" 2>&1 || code=$?
  [ "$code" -eq 2 ] || { cat "$work/refusal.log"; echo "expected exit code 2, got $code"; exit 1; }
  grep -qF -- "$fragment" "$work/refusal.log" ||
    { cat "$work/refusal.log"; echo "output lacks '$fragment'"; exit 1; }
}

echo "-- 1. a second sequence in the world of the first"
"$superdyna" simulate --out "$work/a" --scene street --dynamic none --duration 5 --seed 5 \
  --landmarks 0 >/dev/null 2>&1
"$superdyna" simulate --out "$work/b" --world-of "$work/a" --dynamic low --duration 3 --start 1 \
  --seed 6 --landmarks 0 >/dev/null 2>&1
fingerprint() { grep 'static_world_fingerprint' "$1/simulation.yaml"; }
[ "$(fingerprint "$work/a")" = "$(fingerprint "$work/b")" ] ||
  { echo "the static worlds differ"; exit 1; }
grep -q "^world_of: $work/a" "$work/b/simulation.yaml" || { echo "no world_of line"; exit 1; }
cmp -s "$work/a/mav0/cam0/data.csv" "$work/b/mav0/cam0/data.csv" &&
  { echo "the second sequence has the first one's frames"; exit 1; }
expect_refusal "is a street scene" "$superdyna" simulate --out "$work/c" --world-of "$work/a" \
  --scene indoor --duration 2
expect_refusal "has background contrast 1" "$superdyna" simulate --out "$work/c" \
  --world-of "$work/a" --background-contrast 0.5 --duration 2
expect_refusal "has texture variety 0" "$superdyna" simulate --out "$work/c" \
  --world-of "$work/a" --texture-variety 2 --duration 2
mkdir -p "$work/a-edited"
sed 's/^  background_contrast: 1$/  background_contrast: 2/' "$work/a/simulation.yaml" \
  >"$work/a-edited/simulation.yaml"
expect_refusal "world_source.background_contrast" "$superdyna" simulate --out "$work/c" \
  --world-of "$work/a-edited" --duration 2
sed 's/^  texture_variety: 0$/  texture_variety: -3/' "$work/a/simulation.yaml" \
  >"$work/a-edited/simulation.yaml"
expect_refusal "world_source.texture_variety" "$superdyna" simulate --out "$work/c" \
  --world-of "$work/a-edited" --duration 2
echo "world reused, fingerprint $(fingerprint "$work/a")"

echo "-- 2. saving a map, refused combinations"
"$superdyna" run --path "$work/a" --mode stereo-inertial --deterministic --output "$work/a.tum" \
  --save-map "$work/a.sdmap" >"$work/a.log" 2>&1 || { cat "$work/a.log"; exit 1; }
grep '^map saved to' "$work/a.log"
[ -s "$work/a.sdmap" ] || { echo "no map file"; exit 1; }
if ls "$work" | grep -q '\.tmp-'; then echo "a temporary file was left"; exit 1; fi
run_b=("$superdyna" run --path "$work/b" --mode stereo-inertial --deterministic --output "$work/b.tum")
expect_refusal "needs a map to track against: add --load-map" "${run_b[@]}" --localization-only
expect_refusal "add --localization-only" "${run_b[@]}" --load-map "$work/a.sdmap"
expect_refusal "is also an input or another output" "${run_b[@]}" --load-map "$work/a.sdmap" \
  --localization-only --save-map "$work/a.sdmap"
head -c 2000 "$work/a.sdmap" >"$work/truncated.sdmap"
expect_refusal "truncated: the header announces" "${run_b[@]}" --load-map "$work/truncated.sdmap" \
  --localization-only
expect_refusal "the map was made in stereo-inertial mode, this run is stereo" \
  "$superdyna" run --path "$work/b" --mode stereo --output "$work/b.tum" \
  --load-map "$work/a.sdmap" --localization-only
echo "refusals ok"

echo "-- 3. localization-only against the loaded map"
"${run_b[@]}" --load-map "$work/a.sdmap" --localization-only --save-map "$work/b.sdmap" \
  >"$work/b.log" 2>&1 || { cat "$work/b.log"; exit 1; }
grep -E '^localization-only|^ATE|frames in' "$work/b.log"
cmp "$work/a.sdmap" "$work/b.sdmap" || { echo "localization-only changed the map"; exit 1; }

echo "-- 4. the first run's alignment applied to the second"
"$superdyna" eval --gt "$work/a/mav0/state_groundtruth_estimate0/data.csv" --est "$work/a.tum" \
  --json "$work/a.json" >/dev/null
gt_b="$work/b/mav0/state_groundtruth_estimate0/data.csv"
"$superdyna" eval --gt "$gt_b" --est "$work/b.tum" --alignment "$work/a.json" \
  --json "$work/b_given.json" >"$work/given.log"
"$superdyna" eval --gt "$gt_b" --est "$work/b.tum" --alignment-from "$work/a.tum" \
  --alignment-gt "$work/a/mav0/state_groundtruth_estimate0/data.csv" \
  --json "$work/b_borrowed.json" >"$work/borrowed.log"
grep -q 'given' "$work/given.log" || { cat "$work/given.log"; echo "alignment not given"; exit 1; }
ate() { sed -n 's/.*"ate_rmse": *\([0-9.e+-]*\).*/\1/p' "$1" | head -1; }
python3 - "$(ate "$work/b_given.json")" "$(ate "$work/b_borrowed.json")" <<'PY'
import sys
given, borrowed = map(float, sys.argv[1:3])
print(f"second run, first run's alignment: ATE {given:.4f} m (borrowed: {borrowed:.4f} m)")
assert abs(given - borrowed) < 1e-6 * max(1.0, given), "--alignment and --alignment-from differ"
assert given < 0.05, "ATE above 5 cm with the first run's alignment"
PY
expect_refusal "--alignment-from and --alignment-gt go together" "$superdyna" eval --gt "$gt_b" \
  --est "$work/b.tum" --alignment-from "$work/a.tum"
echo "map cli test passed"

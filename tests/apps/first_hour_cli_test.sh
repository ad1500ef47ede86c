#!/usr/bin/env bash
# End-to-end checks of what a new user meets first (issue 54), one case per ctest test:
#   eval_short_path      eval on a path shorter than the RPE delta prints the ATE, skips the RPE
#                        with a warning naming --rpe-delta, and exits 0.
#   run_input_error      a damaged image in the middle of a sequence stops the run with exit code
#                        2 and a message naming the frame and the file, and the trajectory of the
#                        frames before it is written whole (no temporary file left), sequential
#                        and concurrent.
#   exit_codes           usage errors exit with 1, bad input with 2, as --help documents.
#   run_output           run without --mode takes the dataset's sensors and says so; the options
#                        dump only with --print-config; one line per inertial initialisation stage;
#                        --quiet leaves warnings and the summary.
#   eval_plot_span       eval --plot shows the ground truth of the estimate's time span by default
#                        (--plot-span all: all of it).
#   world_of_range       simulate --world-of with --start + --duration inside the first sequence's
#                        part fits; a part outside its world, or beyond a trajectory file's end,
#                        is refused with the range that fits.
#   eval_undetermined_rotation
#                        an alignment whose rotation a path of a few centimetres does not
#                        determine is flagged in the table, the JSON and a warning; a real flight
#                        is not.
# Usage: first_hour_cli_test.sh SUPERDYNA CASE
set -euo pipefail
superdyna=$1 case=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

fail() { echo "FAIL: $*"; exit 1; }

# Writes a TUM trajectory of N poses 50 ms apart: a wobble of AMPLITUDE metres along x and y with
# a climb of CLIMB metres per pose, plus NOISE metres of deterministic jitter on x (the estimate).
write_path() {  # file poses amplitude climb noise
  python3 - "$@" <<'PY'
import math, sys
path, n, amplitude, climb, noise = sys.argv[1], int(sys.argv[2]), *map(float, sys.argv[3:6])
with open(path, "w") as out:
    for i in range(n):
        x = amplitude * math.sin(0.3 * i) + noise * math.sin(2.7 * i + 1.0)
        y = amplitude * math.cos(0.2 * i)
        out.write("%.3f %.9f %.9f %.9f 0 0 0 1\n" % (0.05 * i, x, y, climb * i))
PY
}

case_eval_short_path() {
  # 95 poses over 4.7 s and 0.23 m of path (as the EuRoC excerpt's standing start): no pair is
  # 1 m apart.
  write_path "$work/gt.txt" 95 0.01 0.0002 0
  write_path "$work/est.txt" 95 0.01 0.0002 0.002
  local code=0
  "$superdyna" eval --gt "$work/gt.txt" --est "$work/est.txt" --json "$work/eval.json" \
    >"$work/eval.log" 2>&1 || code=$?
  cat "$work/eval.log"
  [ "$code" -eq 0 ] || fail "exit code $code, expected 0"
  grep -q '^ATE trans \[m\] ' "$work/eval.log" || fail "no ATE row"
  grep -q 'est.txt: RPE: no pose pair is 1 m apart (.*): the RPE is left out' "$work/eval.log" ||
    fail "no warning that the RPE was left out"
  grep -q '^RPE: *not computed (no pose pair is 1 m apart' "$work/eval.log" ||
    fail "the table does not say why the RPE is missing"
  grep -q -- '--rpe-delta' "$work/eval.log" || fail "the hint does not name --rpe-delta"
  if grep -q -- '--delta' <(sed 's/--rpe-delta//g' "$work/eval.log"); then
    fail "the hint names --delta, which does not exist"
  fi
  grep -q '^RPE trans \[m/m\] *n/a' "$work/eval.log" || fail "the RPE row is not n/a"
  python3 - "$work/eval.json" <<'PY'
import json, sys
report = json.load(open(sys.argv[1]))
assert report["rpe_trans"] is None and "1 m apart" in report["rpe_missing"], report
assert 0.0005 < report["ate_rmse"] < 0.003, report["ate_rmse"]
print("ATE rmse %.4f m over %d pairs; RPE null" % (report["ate_rmse"], report["pairs"]))
PY
  # A delta the path holds gives an RPE again.
  "$superdyna" eval --gt "$work/gt.txt" --est "$work/est.txt" --rpe-delta 0.05 >"$work/rpe.log"
  grep -q '^RPE trans \[m/m\] *[0-9]' "$work/rpe.log" || fail "no RPE with --rpe-delta 0.05"
}

# A short simulated EuRoC-layout sequence (20 Hz stereo + IMU) in $work/seq.
simulate_short() {  # duration [extra simulate options...]
  local duration=$1
  shift
  "$superdyna" simulate --out "$work/seq" --scene street --dynamic none --duration "$duration" \
    --seed 5 --landmarks 0 "$@" >/dev/null 2>&1 || fail "simulate failed"
}

case_run_input_error() {
  simulate_short 1.5
  local frames damaged
  frames=$(grep -vc '^#' "$work/seq/mav0/cam0/data.csv")
  damaged=$(grep -v '^#' "$work/seq/mav0/cam0/data.csv" | sed -n 13p | cut -d, -f2 | tr -d '\r')
  head -c 300 /dev/urandom >"$work/seq/mav0/cam0/data/$damaged"  # frame 12 (0-based)
  local pipeline
  for pipeline in --deterministic ""; do
    echo "-- run ${pipeline:-(concurrent)}"
    mkdir -p "$work/out"
    rm -f "$work/out/"*
    local code=0
    # shellcheck disable=SC2086
    "$superdyna" run --path "$work/seq" --mode stereo $pipeline --output "$work/out/traj.tum" \
      >"$work/run.log" 2>&1 || code=$?
    grep -v '^  ' "$work/run.log"
    [ "$code" -eq 2 ] || fail "exit code $code, expected 2"
    grep -q "^stopped by an input error at frame 12 of $frames (0-based index, file .*cam0/data/$damaged)" \
      "$work/run.log" || fail "no line naming frame 12 and its file"
    grep -q "cannot decode the image" "$work/run.log" || fail "the error itself is not printed"
    [ -f "$work/out/traj.tum" ] || fail "no trajectory written"
    local poses
    poses=$(grep -vc '^#' "$work/out/traj.tum")
    [ "$poses" -eq 12 ] || fail "expected the 12 poses of the frames before the damaged one, got $poses"
    awk '!/^#/ && NF != 8 { exit 1 }' "$work/out/traj.tum" || fail "a truncated pose row"
    [ -s "$work/out/traj_keyframes.tum" ] || fail "no keyframe trajectory"
    if ls "$work/out" | grep -q '\.tmp-'; then fail "a temporary file was left"; fi
  done
}

# Runs COMMAND, expecting exit code CODE and FRAGMENT in its output.
expect_exit() {  # code fragment command...
  local expected=$1 fragment=$2 code=0
  shift 2
  "$@" >"$work/expect.log" 2>&1 || code=$?
  [ "$code" -eq "$expected" ] ||
    { cat "$work/expect.log"; fail "expected exit code $expected, got $code: $*"; }
  grep -qF -- "$fragment" "$work/expect.log" ||
    { cat "$work/expect.log"; fail "output lacks '$fragment'"; }
}

case_exit_codes() {
  mkdir -p "$work/empty"
  echo "0 0 0 0 0 0 0 1" >"$work/x.tum"
  local command
  for command in run eval info ""; do
    # shellcheck disable=SC2086  # no argument for the top-level help
    expect_exit 0 "Exit codes: 0 ok, 1 usage error" "$superdyna" $command --help
    [ "$(grep -c "^Exit codes:" "$work/expect.log")" -eq 1 ] ||
      { cat "$work/expect.log"; fail "'superdyna $command --help' lists the exit codes more than once"; }
  done
  expect_exit 1 "--path: Path does not exist" \
    "$superdyna" run --path "$work/missing/" --output "$work/x.tum"
  expect_exit 1 "--output is required" "$superdyna" run --path "$work/empty"
  expect_exit 1 "The following argument was not expected: --bogus" \
    "$superdyna" eval --gt "$work/x.tum" --est "$work/x.tum" --bogus
  expect_exit 1 "A subcommand is required" "$superdyna"
  # Bad input (here a dataset folder without cam0) is exit code 2.
  expect_exit 2 "cam0" "$superdyna" info --dataset euroc --path "$work/empty"
  cat "$work/expect.log"
}

case_run_output() {
  simulate_short 6 --drop-frames 60
  # The first refinement of the inertial initialisation (default: at a map age of 5 s) early
  # enough for 6 s.
  printf 'mapping:\n  refine_first_s: 4.5\n' >"$work/options.yaml"
  local run=("$superdyna" run --path "$work/seq" --deterministic --config "$work/options.yaml")
  echo "-- no --mode: the dataset's sensors"
  "${run[@]}" --output "$work/a.tum" >"$work/a.log" 2>&1 || { cat "$work/a.log"; fail "run failed"; }
  grep -v '^frame ' "$work/a.log"
  grep -q '^mode: stereo-inertial (the dataset has two cameras and an IMU; --mode chooses another)$' \
    "$work/a.log" || fail "no line saying the mode was taken from the dataset"
  grep -q '^running stereo-inertial SLAM' "$work/a.log" || fail "not run stereo-inertially"
  grep -q "^effective options written to $work/a_config.yaml (--print-config prints them)$" \
    "$work/a.log" || fail "no line naming the options file"
  [ "$(grep -c ':' "$work/a_config.yaml")" -gt 240 ] || fail "the options file is not complete"
  if grep -q '^  [a-z_]*: ' "$work/a.log"; then fail "options dumped without --print-config"; fi
  [ "$(grep -c '^inertial initialisation: stage 1 of 3 (gravity, velocities and IMU biases) at frame [0-9]*, [0-9.]* s into the run; map of [0-9]* keyframes$' "$work/a.log")" -eq 1 ] ||
    fail "not one line for the first inertial stage"
  [ "$(grep -c '^inertial initialisation: stage 2 of 3 (first refinement)' "$work/a.log")" -eq 1 ] ||
    fail "not one line for the second inertial stage"
  [ "$(grep -c '^inertial initialisation' "$work/a.log")" -eq 2 ] || fail "other stage lines"
  [ "$(wc -l <"$work/a.log")" -lt 40 ] || fail "$(wc -l <"$work/a.log") lines printed"
  echo "-- --quiet: warnings and the summary"
  "${run[@]}" --output "$work/q.tum" --quiet >"$work/q.log" 2>&1 || fail "quiet run failed"
  cat "$work/q.log"
  grep -q '^warning: .*cam0/data.csv: about 1 dropped frame' "$work/q.log" ||
    fail "--quiet dropped a warning"
  grep -q ' frames in .* s (.* FPS)' "$work/q.log" || fail "--quiet dropped the summary"
  grep -q '^ATE (SE(3) aligned): rmse' "$work/q.log" || fail "--quiet dropped the ATE"
  if grep -qE '^(frame |running |mode: |effective options|inertial initialisation|segmentation: [a-z]+$)' \
    "$work/q.log"; then fail "--quiet printed progress"; fi
  cmp -s "$work/a.tum" "$work/q.tum" || fail "--quiet changed the trajectory"
  echo "-- --print-config"
  "${run[@]}" --mode stereo --max-frames 3 --output "$work/p.tum" --print-config >"$work/p.log" 2>&1
  grep -q "^effective options (written to $work/p_config.yaml):$" "$work/p.log" ||
    fail "--print-config did not print the options"
  [ "$(grep -c '^  [a-z_0-9]*: ' "$work/p.log")" -gt 240 ] || fail "not every key printed"
  expect_exit 1 "--mode: stereo-imu not in" \
    "${run[@]}" --mode stereo-imu --output "$work/x.tum"
  echo "-- the mode of a dataset without an IMU, of one camera and an IMU"
  cp -r "$work/seq" "$work/stereo" && rm -r "$work/stereo/mav0/imu0"
  "$superdyna" run --path "$work/stereo" --max-frames 3 --output "$work/s.tum" >"$work/s.log" 2>&1 ||
    { cat "$work/s.log"; fail "stereo run failed"; }
  grep -q '^mode: stereo (the dataset has two cameras; --mode chooses another)$' "$work/s.log" ||
    { cat "$work/s.log"; fail "not stereo"; }
  cp -r "$work/seq" "$work/mono" && rm -r "$work/mono/mav0/cam1"
  "$superdyna" run --path "$work/mono" --max-frames 3 --output "$work/m.tum" >"$work/m.log" 2>&1 ||
    { cat "$work/m.log"; fail "mono-inertial run failed"; }
  grep -q '^mode: mono-inertial (the dataset has one camera and an IMU; --mode chooses another)$' \
    "$work/m.log" || { cat "$work/m.log"; fail "not mono-inertial"; }
}

# x extents (pixels) of the ground truth's and the first estimate's polylines of an SVG plot.
polyline_extents() {  # svg
  python3 - "$1" <<'PY'
import re, sys
lines = re.findall(r'<polyline points="([^"]*)"', open(sys.argv[1]).read())
def extent(points):
    xs = [float(p.split(",")[0]) for p in points.split()]
    return max(xs) - min(xs)
print("%.1f %.1f" % (extent(lines[0]), extent(lines[1])))
PY
}

case_eval_plot_span() {
  "$superdyna" demo --out "$work/demo" --duration 60 >/dev/null 2>&1
  sed -n '400,500p' "$work/demo/estimate.txt" >"$work/part.txt"  # 5 s of the 60 s
  "$superdyna" eval --gt "$work/demo/groundtruth.txt" --est "$work/part.txt" \
    --plot "$work/part.svg" >"$work/plot.log" 2>&1
  cat "$work/plot.log"
  grep -qF "part.svg: ground truth from 19.90 s to 24.90 s of its 60.00 s (the estimate's time span" \
    "$work/plot.log" || fail "the plot line does not give the estimate's span"
  read -r gt_px est_px < <(polyline_extents "$work/part.svg")
  echo "estimate's span: ground truth ${gt_px} px wide, estimate ${est_px} px"
  python3 -c "import sys; sys.exit(0 if $est_px > 0.8 * $gt_px else 1)" ||
    fail "the ground truth is wider than the estimate's span"
  "$superdyna" eval --gt "$work/demo/groundtruth.txt" --est "$work/part.txt" \
    --plot "$work/all.svg" --plot-span all >/dev/null 2>&1
  read -r gt_px est_px < <(polyline_extents "$work/all.svg")
  echo "--plot-span all: ground truth ${gt_px} px wide, estimate ${est_px} px"
  python3 -c "import sys; sys.exit(0 if $est_px < 0.6 * $gt_px else 1)" ||
    fail "--plot-span all does not show the whole ground truth"
}

case_world_of_range() {
  "$superdyna" simulate --out "$work/a" --scene street --dynamic none --duration 5 --seed 5 \
    --landmarks 0 >/dev/null 2>&1 || fail "simulate a failed"
  # Inside the first sequence's 5 s: fits (it was refused as "covers 4.5 s").
  "$superdyna" simulate --out "$work/b" --world-of "$work/a" --dynamic none --start 2 \
    --duration 2.5 --seed 6 --landmarks 0 >"$work/b.log" 2>&1 || { cat "$work/b.log"; fail "refused"; }
  [ "$(grep -vc '^#' "$work/b/mav0/cam0/data.csv")" -eq 51 ] || fail "expected 51 frames in 2.5 s"
  # Far along the flight, outside the first sequence's world: refused, naming the part that fits.
  expect_exit 2 "choose a part of the trajectory within it; the part of the trajectory its world was built around fits: --start 0 --duration 5" \
    "$superdyna" simulate --out "$work/c" --world-of "$work/a" --dynamic none --start 40 \
    --duration 2 --landmarks 0
  # A trajectory file: the longest duration for the start given.
  "$superdyna" demo --out "$work/demo" --duration 6 >/dev/null 2>&1
  expect_exit 2 "--start + --duration must be at most 6.00 s (with --start 2.00 s, --duration up to 4.00 s)" \
    "$superdyna" simulate --out "$work/d" --trajectory "$work/demo/groundtruth.txt" --start 2 \
    --duration 5
  cat "$work/expect.log"
}

case_eval_undetermined_rotation() {
  # A 95-pose hover over 2 cm with 3 mm of estimate noise.
  python3 - "$work/gt.txt" "$work/est.txt" <<'PY'
import math, random, sys
random.seed(3)
with open(sys.argv[1], "w") as gt, open(sys.argv[2], "w") as est:
    for i in range(95):
        p = (0.02 * math.sin(0.05 * i), 0.002 * math.cos(0.3 * i), 0.001 * math.sin(0.2 * i))
        e = [random.gauss(0.0, 0.003) for _ in range(3)]
        gt.write("%.3f %.9f %.9f %.9f 0 0 0 1\n" % (0.05 * i, *p))
        est.write("%.3f %.9f %.9f %.9f 0 0 0 1\n" % (0.05 * i, *(a + b for a, b in zip(p, e))))
PY
  "$superdyna" eval --gt "$work/gt.txt" --est "$work/est.txt" --rpe-delta 0.005 \
    --json "$work/hover.json" >"$work/hover.log" 2>&1
  cat "$work/hover.log"
  grep -q '^Alignment: .*rotation NOT determined by this path (uncertain by about [0-9]* deg)' \
    "$work/hover.log" || fail "the table does not flag the rotation"
  grep -q 'the path does not determine the alignment.s rotation' "$work/hover.log" ||
    fail "no warning"
  python3 - "$work/hover.json" <<'PY'
import json, sys
alignment = json.load(open(sys.argv[1]))["alignment"]
assert alignment["rotation_determined"] is False, alignment
assert alignment["rotation_uncertainty_deg"] > 30, alignment
PY
  "$superdyna" demo --out "$work/demo" >/dev/null 2>&1
  "$superdyna" eval --gt "$work/demo/groundtruth.txt" --est "$work/demo/estimate.txt" \
    --json "$work/flight.json" >"$work/flight.log" 2>&1
  if grep -q 'NOT determined\|does not determine' "$work/flight.log"; then
    cat "$work/flight.log"
    fail "a real flight was flagged"
  fi
  python3 - "$work/flight.json" <<'PY'
import json, sys
alignment = json.load(open(sys.argv[1]))["alignment"]
assert alignment["rotation_determined"] is True and alignment["rotation_uncertainty_deg"] < 5, alignment
PY
}

"case_$case"
echo "$case: passed"

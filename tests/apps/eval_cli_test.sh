#!/usr/bin/env bash
# End-to-end checks of `superdyna eval`, `superdyna demo`, `superdyna info` and `run`'s outputs:
#  1. ATE / RPE from the CLI equal an independent numpy computation (scripts/reference_eval.py)
#     to 1e-6 relative, for SE(3) and Sim(3) alignment, on a generated flight and (when
#     ../shared is present) on a real EuRoC ground truth with a simulated drifting estimate;
#  2. bad input stops with exit code 2 and a message naming the file and line;
#  3. an output path equal to an input is refused and the input left intact;
#  4. `run` writes its effective options, and reloading them reproduces the run byte for byte;
#  5. `eval --camera-frame` evaluates the camera's poses (a mono-like estimate).
# Usage: eval_cli_test.sh SUPERDYNA PYTHON REPO_DIR SHARED_DIR ($SUPERDYNA_SHARED_DIR overrides it)
# A missing ../shared part is left out with a message, or fails the test when
# $SUPERDYNA_REQUIRE_SHARED is 1 (CI), as in the C++ tests (tests/support/test_support.h).
set -euo pipefail
superdyna=$1 python=$2 repo=$3 shared=${SUPERDYNA_SHARED_DIR:-$4}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
keys=(pairs scale ate_rmse ate_mean ate_median ate_std ate_min ate_max rpe_trans rpe_trans_mean
      rpe_rot rpe_rot_mean rpe_pairs)

# True when the shared file or folder RELATIVE exists; otherwise prints what is left out and
# returns false, or exits with failure when shared data is required.
have_shared() {  # relative what-is-left-out
  [ -e "$shared/$1" ] && return 0
  echo "shared data '$1' not found under $shared (set SUPERDYNA_SHARED_DIR): $2"
  [ "${SUPERDYNA_REQUIRE_SHARED:-}" != 1 ] || exit 1
  return 1
}

compare_with_reference() {  # folder with groundtruth.txt and estimate.txt
  local dir=$1 align
  for align in se3 sim3; do
    "$superdyna" eval --gt "$dir/groundtruth.txt" --est "$dir/estimate.txt" --align "$align" \
      --json "$dir/cli_$align.json" >/dev/null
    "$python" "$repo/scripts/reference_eval.py" --gt "$dir/groundtruth.txt" \
      --est "$dir/estimate.txt" --align "$align" >"$dir/ref_$align.json"
    echo "-- $dir, $align"
    "$python" "$repo/tests/apps/compare_json.py" "$dir/cli_$align.json" "$dir/ref_$align.json" \
      "${keys[@]}" --rtol 1e-6
  done
}

expect_failure() {  # expected-message-fragment command...
  local fragment=$1 message code
  shift
  set +e
  message=$("$@" 2>&1)
  code=$?
  set -e
  echo "$message"
  [ "$code" -eq 2 ] || { echo "expected exit code 2, got $code"; exit 1; }
  grep -qF "$fragment" <<<"$message" || { echo "message lacks '$fragment'"; exit 1; }
}

"$superdyna" demo --out "$work/generated" --scale 1.05 >/dev/null
compare_with_reference "$work/generated"

euroc_gt=data/trajectories/euroc/V1_01_easy.txt
if have_shared "$euroc_gt" "no real-trajectory comparison"; then
  "$superdyna" demo --out "$work/euroc" --gt "$shared/$euroc_gt" --scale 0.93 --seed 7 >/dev/null
  compare_with_reference "$work/euroc"
fi

# Bad input: a NaN in line 3 of the estimate.
sed '3s/^\([^ ]*\) [^ ]*/\1 nan/' "$work/generated/estimate.txt" >"$work/bad.txt"
expect_failure "bad.txt:3 [tx]: 'nan' is not finite" \
  "$superdyna" eval --gt "$work/generated/groundtruth.txt" --est "$work/bad.txt"

# Never overwrite an input.
cp "$work/generated/estimate.txt" "$work/keep.txt"
expect_failure "is an input file; refusing to overwrite it" \
  "$superdyna" eval --gt "$work/generated/groundtruth.txt" --est "$work/keep.txt" \
  --json "$work/keep.txt"
cmp -s "$work/keep.txt" "$work/generated/estimate.txt" || { echo "input was modified"; exit 1; }
# Dataset summary: the real EuRoC excerpt, and a clear error for a folder without mav0/.
euroc_dir=data/euroc/V1_01_easy_micro
if have_shared "$euroc_dir" "no summary of a real sequence"; then
  "$superdyna" info --dataset euroc --path "$shared/$euroc_dir" | tee "$work/info.txt"
  grep -q "stereo pairs: 95" "$work/info.txt" || { echo "info lacks the 95 stereo pairs"; exit 1; }
fi
mkdir -p "$work/empty"
expect_failure "cam0" "$superdyna" info --dataset euroc --path "$work/empty"
# Bad mover options stop `simulate` with the option named, before it writes anything.
expect_failure "option 'pattern-distance': expected MIN,MAX with 1 <= MIN <= MAX <= 50 m, got 6,3" \
  "$superdyna" simulate --out "$work/bad_sim" --dynamic-pattern crowd --pattern-distance 6,3
expect_failure "option 'dynamic-pattern': pattern 'bus' needs a street or parking scene" \
  "$superdyna" simulate --out "$work/bad_sim" --scene indoor --dynamic-pattern bus
[ ! -e "$work/bad_sim" ] || { echo "a refused simulation wrote $work/bad_sim"; exit 1; }
# `run` never writes its trajectory over a file of the dataset.
"$superdyna" simulate --out "$work/tiny" --duration 0.5 --dynamic none --landmarks 0 >/dev/null
gt_csv="$work/tiny/mav0/state_groundtruth_estimate0/data.csv"
cp "$gt_csv" "$work/gt_copy.csv"
expect_failure "is a file of the dataset; refusing to overwrite it" \
  "$superdyna" run --dataset euroc --path "$work/tiny" --mode stereo --output "$gt_csv"
cmp -s "$gt_csv" "$work/gt_copy.csv" || { echo "dataset file was modified"; exit 1; }
# --camera-frame: a visual mono map's unit (here 0.2 m) with the metric camera-body lever arm puts
# the body off in a way no similarity removes; the camera's poses are exact up to the scale.
"$python" - "$work/generated/groundtruth.txt" "$work/tiny/mav0/cam0/sensor.yaml" \
  "$work/mono.txt" <<'PY'
import re, sys
import numpy as np
def rot(q):
    x, y, z, w = q
    return np.array([[1-2*(y*y+z*z), 2*(x*y-z*w), 2*(x*z+y*w)],
                     [2*(x*y+z*w), 1-2*(x*x+z*z), 2*(y*z-x*w)],
                     [2*(x*z-y*w), 2*(y*z+x*w), 1-2*(x*x+y*y)]])
gt = np.loadtxt(sys.argv[1])
values = re.search(r"T_BS:.*?data:\s*\[([^\]]*)\]", open(sys.argv[2]).read(), re.S).group(1)
T_b_c = np.array([float(v) for v in values.split(",")]).reshape(4, 4)
with open(sys.argv[3], "w") as out:
    for row in gt:
        T_w_b = np.eye(4)
        T_w_b[:3, :3], T_w_b[:3, 3] = rot(row[4:8]), row[1:4]
        T_w_c = T_w_b @ T_b_c
        T_w_c[:3, 3] *= 0.2                          # the map's own unit
        p = (T_w_c @ np.linalg.inv(T_b_c))[:3, 3]    # the body through the metric lever arm
        out.write("%.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n" % (row[0], *p, *row[4:8]))
PY
ate_rmse() { grep "ATE trans" | awk '{print $4}'; }
body=$("$superdyna" eval --gt "$work/generated/groundtruth.txt" --est "$work/mono.txt" \
  --align sim3 | ate_rmse)
camera=$("$superdyna" eval --gt "$work/generated/groundtruth.txt" --est "$work/mono.txt" \
  --align sim3 --camera-frame "$work/tiny/mav0/cam0/sensor.yaml" | ate_rmse)
echo "mono-like estimate: Sim(3) ATE of the body $body m, of the camera $camera m"
"$python" -c "import sys; sys.exit(0 if float('$body') > 0.01 and float('$camera') < 1e-6 else 1)" ||
  { echo "--camera-frame did not evaluate the camera"; exit 1; }
# `run --print-config` prints and writes its effective options; reloaded, they reproduce the run bit for bit.
"$superdyna" run --dataset euroc --path "$work/tiny" --mode stereo-inertial --deterministic \
  --config "$repo/configs/euroc_stereo_inertial.yaml" --output "$work/a.txt" --print-config \
  | tee "$work/run_a.txt"
grep -q "^effective options (written to $work/a_config.yaml):" "$work/run_a.txt" ||
  { echo "run did not print its effective options"; exit 1; }
"$superdyna" run --dataset euroc --path "$work/tiny" --mode stereo-inertial --deterministic \
  --config "$work/a_config.yaml" --output "$work/b.txt" >/dev/null
cmp "$work/a.txt" "$work/b.txt" || { echo "reloaded options changed the trajectory"; exit 1; }
cmp "$work/a_config.yaml" "$work/b_config.yaml" || { echo "reloaded options differ"; exit 1; }
# --online-trajectory writes the poses as tracked beside the keyframe-relative ones, never over
# another output of the run.
"$superdyna" run --dataset euroc --path "$work/tiny" --mode stereo-inertial --deterministic \
  --output "$work/c.txt" --online-trajectory "$work/c_online.txt" | tee "$work/run_c.txt" >/dev/null
[ "$(wc -l <"$work/c_online.txt")" -eq "$(wc -l <"$work/c.txt")" ] ||
  { echo "online and reported trajectories differ in length"; exit 1; }
grep -q "^ATE of the poses as tracked (SE(3) aligned): rmse" "$work/run_c.txt" ||
  { echo "run did not print the ATE of the online poses"; exit 1; }
expect_failure "option '--online-trajectory': '$work/c.txt' is also another output of the run" \
  "$superdyna" run --dataset euroc --path "$work/tiny" --mode stereo --output "$work/c.txt" \
  --online-trajectory "$work/c.txt"
cp "$work/a_config.yaml" "$work/a_config_copy.yaml"
expect_failure "is an input file; refusing to overwrite it" \
  "$superdyna" run --dataset euroc --path "$work/tiny" --mode stereo-inertial \
  --config "$work/a_config.yaml" --output "$work/a.txt"
cmp -s "$work/a_config.yaml" "$work/a_config_copy.yaml" || { echo "--config was modified"; exit 1; }
# The moving-object test needs labelled keypoints; eval-dynamic names the bad field of a log.
expect_failure "option '--dynamic': mode semantic-geometric needs keypoints labelled by a segmenter" \
  "$superdyna" run --dataset euroc --path "$work/tiny" --mode stereo --dynamic semantic-geometric \
  --output "$work/d.txt"
printf 't_ns,instance_id,class,pairs,tested,max_distance_px,threshold_px,decision,keypoints,dropped\n1,2,vehicle,3,3,1.0,2.0,parked,5,0\n' \
  >"$work/bad_dyn.csv"
expect_failure "bad_dyn.csv:2 [decision]: expected moving, static or unverified" \
  "$superdyna" eval-dynamic --log "$work/bad_dyn.csv" --path "$work/tiny"
echo "CLI checks passed"

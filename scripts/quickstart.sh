#!/usr/bin/env bash
# Quick start, step 1: install dependencies, build, and run the main job on the built-in default:
# generate a synthetic street sequence (stereo + IMU + exact ground truth, parked cars and people,
# nothing moving), run stereo-inertial SLAM on it, and evaluate the trajectory against the ground
# truth (ATE, RPE; JSON and a top-view plot). Everything lands in superdyna_demo/ (DEMO_DIR).
set -euo pipefail
repo_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$repo_dir/scripts/setup.sh" superdyna  # the tool only; scripts/test.sh builds the tests
build_dir=${BUILD_DIR:-"$repo_dir/build"}
superdyna="$build_dir/bin/superdyna"
demo_dir=${DEMO_DIR:-"$repo_dir/superdyna_demo"}
sequence="$demo_dir/street_20s"

if [ ! -f "$sequence/simulation.yaml" ]; then
  rm -rf "$sequence"
  "$superdyna" simulate --out "$sequence" --scene street --dynamic none --duration 20 --seed 1
fi
"$superdyna" run --dataset euroc --path "$sequence" --mode stereo-inertial \
  --config "$repo_dir/configs/euroc_stereo_inertial.yaml" --output "$demo_dir/trajectory.txt" \
  --deterministic
"$superdyna" eval --gt "$sequence/mav0/state_groundtruth_estimate0/data.csv" \
  --est "$demo_dir/trajectory.txt" --align se3 --json "$demo_dir/eval.json" \
  --plot "$demo_dir/topview.svg"
echo "Outputs in $demo_dir: the sequence, trajectory.txt (TUM), eval.json, topview.svg"

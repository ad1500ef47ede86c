#!/usr/bin/env bash
# Feature robustness under motion blur and illumination change: simulates seven stereo-inertial
# sequences on real EuRoC motions (V1_03_difficult, V2_03_difficult) with exposure blur, dim light,
# exposure steps and flicker, then runs `superdyna run --mode stereo-inertial --deterministic`
# with each CONFIG and prints lost frames, map resets, frames tracked from the reference keyframe
# and ATE per sequence and config (plus match accuracy against ground truth: median error of the
# projection matches and their share above 5 px, from superdyna_match_accuracy).
# Four sequences are textured with photos (EuRoC V1_01 excerpt and KITTI images from SHARED/data),
# three with the simulator's procedural textures.
# Usage: bench/robustness.sh OUT_DIR [CONFIG ...]
#   OUT_DIR  sequences (kept between runs: delete to regenerate), trajectories, logs, results.md
#            (one row per run) and summary.md (per sequence and config: median over the seeds)
#   CONFIG   default: configs/euroc_stereo_inertial.yaml configs/euroc_stereo_inertial_xfeat.yaml
# Environment: SHARED (default ../shared beside the repository), SUPERDYNA_MODEL_DIR (default
# SHARED/models), BUILD (default build), SEED_OFFSETS (default "0": each offset k adds k to
# every sequence's simulator seed, so "0 1 2" runs three versions of each sequence; single runs
# on dim, blurred sequences are chaotic). Takes about 25 minutes on 2 cores for two configs and
# one seed. bench/robustness_summary.sh RESULTS.md ... summarises the rows of several OUT_DIRs.
set -euo pipefail
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
if [ $# -lt 1 ]; then
  sed -n '2,18p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
  exit 1
fi
out=$(mkdir -p "$1" && cd "$1" && pwd)
shift
configs=("$@")
[ ${#configs[@]} -gt 0 ] ||
  configs=("$repo/configs/euroc_stereo_inertial.yaml" "$repo/configs/euroc_stereo_inertial_xfeat.yaml")
shared=${SHARED:-$repo/../shared}
build=${BUILD:-$repo/build}
superdyna=$build/bin/superdyna
accuracy=$build/bin/superdyna_match_accuracy
export SUPERDYNA_MODEL_DIR=${SUPERDYNA_MODEL_DIR:-$shared/models}
trajectories=$shared/data/trajectories/euroc
for f in "$superdyna" "$accuracy"; do
  [ -x "$f" ] || { echo "$f not built (scripts/setup.sh builds it)" >&2; exit 2; }
done
[ -d "$trajectories" ] || { echo "no EuRoC trajectories under $shared/data (set SHARED)" >&2; exit 2; }

# Photos for --textures: every 10th image of the EuRoC excerpt, every 5th KITTI image (links).
textures=$out/textures
if [ ! -d "$textures" ]; then
  mkdir -p "$textures"
  i=0
  for f in $(ls "$shared"/data/euroc/V1_01_easy_micro/mav0/cam0/data/*.png | awk 'NR % 10 == 1') \
    $(ls "$shared"/data/kitti/snippet_1/image_l/*.png | awk 'NR % 5 == 1'); do
    ln -s "$f" "$textures/$(printf 'photo_%02d.png' "$i")"
    i=$((i + 1))
  done
fi

# name | simulate options (all: --scene indoor --dynamic none, V1_03 from 10 s unless given)
sequences=(
  "photo_sharp|--duration 20 --seed 3 --textures $textures"
  "photo_blur35_gain02|--duration 20 --seed 3 --textures $textures --exposure-ms 35 --blur-step 2 --illumination flicker --illumination-flicker 0.05 --illumination-gain 0.2"
  "photo_dim008_steps|--duration 20 --seed 3 --textures $textures --illumination steps,flicker --illumination-flicker 0.05 --illumination-step 1.0 --illumination-step-interval 4 --illumination-gain 0.08"
  "photo_steps025|--duration 20 --seed 3 --textures $textures --illumination steps,flicker --illumination-flicker 0.1 --illumination-step 1.0 --illumination-step-interval 3 --illumination-gain 0.25"
  "dark_blur20|--duration 40 --seed 3 --illumination-gain 0.35 --illumination flicker --illumination-flicker 0.05 --exposure-ms 20 --blur-step 2"
  "v203_steps_blur15|--trajectory $trajectories/V2_03_difficult.txt --duration 40 --seed 5 --illumination-gain 0.6 --illumination steps,drift --illumination-step 0.8 --exposure-ms 15 --blur-step 2"
  "blur40_steps_gain04|--duration 20 --seed 3 --exposure-ms 40 --blur-step 2 --illumination steps,flicker --illumination-flicker 0.05 --illumination-step 1.0 --illumination-step-interval 4 --illumination-gain 0.4"
)

results=$out/results.md
{
  echo "| sequence | seed | config | lost / resets | from reference | ATE RMSE [m] | match median [px] | > 5 px |"
  echo "|---|---|---|---|---|---|---|---|"
} >"$results"
read -r -a seed_offsets <<<"${SEED_OFFSETS:-0}"
runs=()
for offset in "${seed_offsets[@]}"; do
  [[ $offset =~ ^[0-9]+$ ]] || { echo "SEED_OFFSETS: '$offset' is not a non-negative integer" >&2; exit 2; }
  for entry in "${sequences[@]}"; do runs+=("$offset|$entry"); done
done
for run in "${runs[@]}"; do
  offset=${run%%|*}
  entry=${run#*|}
  base=${entry%%|*}
  options=${entry#*|}
  seed=$(($(echo "$options" | sed -E 's/.*--seed ([0-9]+).*/\1/') + offset))
  options=$(echo "$options" | sed -E "s/--seed [0-9]+/--seed $seed/")
  name=$base
  [ "$offset" = 0 ] || name=${base}_seed$seed
  seq=$out/$name
  if [ ! -f "$seq/mav0/state_groundtruth_estimate0/data.csv" ]; then
    rm -rf "$seq" "$seq.partial"
    echo "simulating $name"
    case "$options" in *--trajectory*) motion=() ;; *) motion=(--trajectory "$trajectories/V1_03_difficult.txt") ;; esac
    # Into a .partial folder first: an interrupted simulation is not taken for a sequence later.
    # shellcheck disable=SC2086
    "$superdyna" simulate --out "$seq.partial" --scene indoor --dynamic none --start 10 "${motion[@]}" \
      $options >"$out/simulate_$name.log" 2>&1 ||
      { echo "simulation of $name failed, see $out/simulate_$name.log" >&2; exit 1; }
    mv "$seq.partial" "$seq"
  fi
  for config in "${configs[@]}"; do
    tag=$(basename "$config" .yaml)
    log=$out/${name}_$tag.log
    echo "running $tag on $name"
    "$superdyna" run --dataset euroc --path "$seq" --mode stereo-inertial --config "$config" \
      --output "$out/${name}_$tag.txt" --frame-log "$out/${name}_$tag.csv" --deterministic \
      >"$log" 2>&1 || { echo "run failed, see $log" >&2; exit 1; }
    lost=$(grep -E '^[0-9]+ frames in' "$log" | sed -E 's/.*lost frames ([0-9]+), map resets ([0-9]+).*/\1 \/ \2/')
    reference=$(grep -E 'reference keyframe' "$log" | sed -E 's/.*: //')
    # The trajectory written (--output), not "ATE of the poses as tracked".
    ate=$(grep -E '^ATE \(' "$log" | head -1 | sed -E 's/.*rmse ([0-9.]+) m.*/\1/')
    match=$("$accuracy" "$seq" "$config" 2>/dev/null | grep -E '^matches')
    median=$(echo "$match" | sed -E 's/.*median ([0-9.]+).*/\1/')
    wrong=$(echo "$match" | sed -E 's/.*>5px ([0-9.]+%).*/\1/')
    echo "| $base | $seed | $tag | $lost | $reference | $ate | $median | $wrong |" >>"$results"
  done
done
echo
cat "$results"
"$repo/bench/robustness_summary.sh" "$results" | tee "$out/summary.md"

#!/usr/bin/env bash
# Keypoint localisation and repeatability of several feature configs on the sequences of
# bench/robustness.sh, in one table: per sequence and config, superdyna_match_accuracy's
# projection matches (count, median error, share within 1 px and beyond 5 px) and the share of
# projected points with a keypoint within 1 px whatever the descriptors say (repeatability).
# Usage: bench/match_accuracy_table.sh OUT_DIR CONFIG[:MODEL] ...
#   OUT_DIR  a bench/robustness.sh output folder (its sequences are used as they are; the table
#            goes to OUT_DIR/match_accuracy.md)
#   CONFIG   a config file; with :MODEL its features.model is replaced (e.g.
#            configs/euroc_stereo_inertial_alike.yaml:alike-s.onnx)
# Environment: BUILD (default build), SUPERDYNA_MODEL_DIR, STEP (every STEP-th frame, default 20).
set -euo pipefail
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
if [ $# -lt 2 ]; then
  sed -n '2,12p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
  exit 1
fi
out=$(cd "$1" && pwd)
shift
accuracy=${BUILD:-$repo/build}/bin/superdyna_match_accuracy
[ -x "$accuracy" ] || { echo "$accuracy not built (scripts/setup.sh builds it)" >&2; exit 2; }
step=${STEP:-20}
mkdir -p "$out/configs"
sequences=()
for gt in "$out"/*/mav0/state_groundtruth_estimate0/data.csv; do
  [ -f "$gt" ] || continue
  seq=${gt%/mav0/*}
  case "$(basename "$seq")" in *_seed*) continue ;; esac  # the first seed of each sequence
  sequences+=("$seq")
done
[ ${#sequences[@]} -gt 0 ] || { echo "no simulated sequence in $out (run bench/robustness.sh first)" >&2; exit 2; }

table=$out/match_accuracy.md
{
  echo "| sequence | config | matches | match median [px] | within 1 px | beyond 5 px | nearest keypoint within 1 px |"
  echo "|---|---|---|---|---|---|---|"
} >"$table"
for seq in "${sequences[@]}"; do
  for spec in "$@"; do
    config=${spec%%:*}
    tag=$(basename "$config" .yaml)
    if [ "$spec" != "$config" ]; then
      model=${spec#*:}
      tag=${tag}_$(basename "$model" .onnx)
      grep -q '^features:' "$config" || { echo "$config has no features section" >&2; exit 2; }
      grep -v '^  model:' "$config" | sed "s|^features:|features:\n  model: $model|" >"$out/configs/$tag.yaml"
      config=$out/configs/$tag.yaml
    fi
    echo "match accuracy: $tag on $(basename "$seq")" >&2
    report=$("$accuracy" "$seq" "$config" 1 "$step" 2>&1) ||
      { echo "superdyna_match_accuracy failed on $seq with $config:" >&2; echo "$report" | tail -3 >&2; exit 1; }
    matches=$(echo "$report" | grep -E '^matches ')
    nearest=$(echo "$report" | grep -E '^nearest ')
    n=$(echo "$matches" | sed -E 's/.*n= *([0-9]+).*/\1/')
    median=$(echo "$matches" | sed -E 's/.*median ([0-9.]+).*/\1/')
    within=$(echo "$matches" | sed -E 's/.*<1px ([0-9.]+%).*/\1/')
    beyond=$(echo "$matches" | sed -E 's/.*>5px ([0-9.]+%).*/\1/')
    repeat=$(echo "$nearest" | sed -E 's/.*<1px ([0-9.]+%).*/\1/')
    echo "| $(basename "$seq") | $tag | $n | $median | $within | $beyond | $repeat |" >>"$table"
  done
done
cat "$table"

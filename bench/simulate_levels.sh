#!/usr/bin/env bash
# Generates every scene at every dynamic level and prints a table of what each contains: frames,
# agents, moving agents in view (mean / max) and the share of the image covered by agents.
# Usage: bench/simulate_levels.sh [DURATION_S=20] [OUT_DIR=/tmp/superdyna_levels] [SEED=1]
set -euo pipefail
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
superdyna=${SUPERDYNA:-$repo/build/bin/superdyna}
duration=${1:-20}
out=${2:-/tmp/superdyna_levels}
seed=${3:-1}
rm -rf "$out"
mkdir -p "$out"
field() { grep -E "^  $1:" "$2" | awk '{print $2}'; }
echo "| scene | level | frames | static agents | moving agents | moving in view (mean / max) | agent pixels | seconds |"
echo "|---|---|---|---|---|---|---|---|"
for scene in street parking indoor; do
  for level in none low mid high; do
    dir="$out/${scene}_$level"
    start=$(date +%s%N)
    "$superdyna" simulate --out "$dir" --scene "$scene" --dynamic "$level" --duration "$duration" \
      --seed "$seed" --landmarks 0 >/dev/null 2>&1
    seconds=$(awk -v a="$start" -v b="$(date +%s%N)" 'BEGIN { print (b - a) / 1e9 }')
    yaml="$dir/simulation.yaml"
    printf "| %s | %s | %s | %s | %s | %s / %s | %.1f %% | %.0f |\n" "$scene" "$level" \
      "$(field frames "$yaml")" "$(field static_agents "$yaml")" "$(field moving_agents "$yaml")" \
      "$(field mean_moving_in_view "$yaml")" "$(field max_moving_in_view "$yaml")" \
      "$(awk -v c="$(field mean_agent_coverage "$yaml")" 'BEGIN { print c * 100 }')" "$seconds"
  done
done

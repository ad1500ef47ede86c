#!/usr/bin/env bash
# The paper's ablations on our sequences: Table 10 (None / S / D / S+D, plus DynaSLAM-style
# `semantic`) and Table 11 (instance masks dilated or eroded by 5 iterations of a 3x3 kernel),
# RUNS runs per cell, scored by `superdyna eval` (ATE median, mean ± 95% CI over the runs).
# Usage: bench/dynamic_ablation.sh RUNS SEQ [SEQ...]
#   SEQ  simulated (or any EuRoC-layout) sequence with instance masks: the folder holding mav0/
# S = learned features (FEATURES, default xfeat), D = dynamic.mode semantic-geometric; every cell
# labels keypoints with the sequence's instance masks and matches class-wise.
# Environment: SUPERDYNA (binary, default build/bin/superdyna), MODE (stereo-inertial),
#   CONFIG (default configs/euroc_stereo_inertial.yaml or euroc_mono_inertial.yaml by MODE),
#   S_CONFIG (the learned-feature cells' config, default the same name with _xfeat),
#   FEATURES (xfeat), DETERMINISTIC (0: concurrent runs, which differ run to run; 1: the
#   sequential pipeline, identical runs - then vary the sequences instead), OUT (output folder),
#   TABLES (10,11: which tables).
set -euo pipefail
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
superdyna=${SUPERDYNA:-$repo/build/bin/superdyna}
if [ $# -lt 2 ]; then
  sed -n '2,14p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
  exit 1
fi
runs=$1
shift
mode=${MODE:-stereo-inertial}
case "$mode" in
  mono-inertial) default_config=$repo/configs/euroc_mono_inertial.yaml ;;
  *) default_config=$repo/configs/euroc_stereo_inertial.yaml ;;
esac
config=${CONFIG:-$default_config}
s_config=${S_CONFIG:-${default_config%.yaml}_xfeat.yaml}
features=${FEATURES:-xfeat}
tables=${TABLES:-10,11}
out=${OUT:-$(mktemp -d "${TMPDIR:-/tmp}/superdyna_ablation.XXXXXX")}
det_flag=""
[ "${DETERMINISTIC:-0}" = 1 ] && det_flag="--deterministic"
mkdir -p "$out"
echo "ablation: mode $mode, config $config (S cells: $s_config), S = $features, $runs runs per cell;" \
  "files in $out"

# cell NAME FEATURES DYNAMIC [EXTRA YAML LINES...]: runs the cell on every sequence and prints a
# row per sequence: name, median, mean ± CI (from superdyna eval's N-run statistics). ORB cells use
# CONFIG, learned-feature cells S_CONFIG.
cell() {
  local name=$1 feats=$2 dyn=$3
  shift 3
  local cfg=$out/$name.yaml
  if [ "$feats" = orb ]; then cp "$config" "$cfg"; else cp "$s_config" "$cfg"; fi
  for line in "$@"; do printf '%s\n' "$line" >>"$cfg"; done
  for seq in "${sequences[@]}"; do
    local tag
    tag=$(basename "$seq")
    local ests=()
    for i in $(seq 1 "$runs"); do
      local traj=$out/${tag}_${name}_$i.txt log=$out/${tag}_${name}_$i.log
      # shellcheck disable=SC2086
      "$superdyna" run --dataset euroc --path "$seq" --mode "$mode" --config "$cfg" \
        --features "$feats" --dynamic "$dyn" --instance-masks --output "$traj" $det_flag \
        >"$log" 2>&1 || { echo "$name run $i on $seq failed, see $log" >&2; tail -3 "$log" >&2; exit 1; }
      ests+=(--est "$traj")
    done
    "$superdyna" eval --gt "$seq/mav0/state_groundtruth_estimate0/data.csv" "${ests[@]}" \
      --json "$out/${tag}_${name}.json" >"$out/${tag}_${name}.eval" 2>&1
    /usr/bin/env python3 - "$out/${tag}_${name}.json" "$name" "$tag" <<'PY' >>"$out/rows.txt"
import json, sys
data = json.load(open(sys.argv[1]))
summary = data.get("summary")
if summary and summary.get("runs", 0) > 1:
    median, mean = summary["ate_rmse_median"], summary["ate_rmse_mean"]
    ci = summary["ate_rmse_ci95_halfwidth"]
    print(f"{sys.argv[3]}|{sys.argv[2]}|{100 * median:.2f}|{100 * mean:.2f} ± {100 * ci:.2f}")
else:
    run = data["runs"][0] if "runs" in data else data
    print(f"{sys.argv[3]}|{sys.argv[2]}|{100 * run['ate_rmse']:.2f}|-")
PY
  done
}

sequences=("$@")
: >"$out/rows.txt"
if [[ $tables == *10* ]]; then
  cell none orb off
  cell S "$features" off
  cell D orb semantic-geometric
  cell SD "$features" semantic-geometric
  cell semantic orb semantic
fi
if [[ $tables == *11* ]]; then
  [[ $tables == *10* ]] || cell SD "$features" semantic-geometric
  cell SD_dilate5 "$features" semantic-geometric "semantics:" "  mask_dilate: 5"
  cell SD_erode5 "$features" semantic-geometric "semantics:" "  mask_erode: 5"
fi

print_table() {
  local title=$1
  shift
  echo
  echo "$title (ATE [cm]: median | mean ± 95% CI over $runs runs)"
  printf '| sequence |'
  for c in "$@"; do printf ' %s |' "$c"; done
  echo
  printf '|---|'
  for _ in "$@"; do printf -- '---|'; done
  echo
  for seq in "${sequences[@]}"; do
    local tag
    tag=$(basename "$seq")
    printf '| %s |' "$tag"
    for c in "$@"; do
      printf ' %s |' "$(awk -F'|' -v t="$tag" -v c="$c" '$1 == t && $2 == c {print $3 " | " $4}' "$out/rows.txt" | sed 's/ | / (/; s/$/)/')"
    done
    echo
  done
}
[[ $tables == *10* ]] && print_table "Table 10 analogue: None / S / D / S+D / semantic (DynaSLAM-style)" none S D SD semantic
[[ $tables == *11* ]] && print_table "Table 11 analogue: S+D with exact, dilated (5) and eroded (5) masks" SD SD_dilate5 SD_erode5
echo
echo "rows: $out/rows.txt"

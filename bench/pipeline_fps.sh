#!/usr/bin/env bash
# Speed of the whole stereo-inertial ORB pipeline (a benchmark, not a test): frames per second of
# `superdyna run` in the deterministic (sequential) and concurrent pipelines, with the per-stage
# breakdown (extract, stereo, track, keyframe + local BA) and the CPU time of each thread.
# The 752x480 synthetic EuRoC-layout sequence (indoor, MH_03 motion, no moving agents) is generated
# once into CACHE_DIR and reused.
# Usage: bench/pipeline_fps.sh [CACHE_DIR=${XDG_CACHE_HOME:-$HOME/.cache}/superdyna_bench]
#                              [DURATION_S=30] [SEED=3]
# Environment: SUPERDYNA (the binary, default build/bin/superdyna), MODES (default
# "deterministic concurrent"), CONFIG (default configs/euroc_stereo_inertial.yaml; e.g.
# configs/euroc_stereo_inertial_xfeat.yaml with SUPERDYNA_MODEL_DIR set for the XFeat pipeline),
# SEQUENCE (a sequence folder to run instead of the generated one, e.g. a `simulate --dynamic high`
# street), RUN_ARGS (more `run` options, e.g. "--instance-masks --dynamic semantic-geometric").
#
# Wall-clock FPS depends on what else runs on the machine; the "CPU-bound FPS" columns estimate the
# rate on 2 otherwise idle cores from CPU times: frames / max(busiest thread, all threads / 2). The
# sequential pipeline's only second thread is the front end's extraction helper (right images,
# features.parallel_extraction), so there the busiest thread is the main one (CPU - helper).
# Threads ONNX Runtime starts itself (features.inference_threads > 1) are not counted.
set -euo pipefail
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
superdyna=${SUPERDYNA:-$repo/build/bin/superdyna}
cache=${1:-${XDG_CACHE_HOME:-$HOME/.cache}/superdyna_bench}
duration=${2:-30}
seed=${3:-3}
modes=${MODES:-deterministic concurrent}
config=${CONFIG:-$repo/configs/euroc_stereo_inertial.yaml}
seq=${SEQUENCE:-$cache/fps_indoor_mh03_${duration}s_seed$seed}
read -r -a run_args <<<"${RUN_ARGS:-}"
trajectory=${SUPERDYNA_SHARED_DIR:-$repo/../shared}/data/trajectories/euroc/MH_03_medium.txt
if [ -n "${SEQUENCE:-}" ]; then
  [ -d "$seq/mav0" ] || { echo "SEQUENCE=$seq: no mav0/ folder in it" >&2; exit 2; }
elif [ ! -f "$seq/simulation.yaml" ]; then
  echo "generating $seq (once)"
  motion=()
  [ -f "$trajectory" ] && motion=(--trajectory "$trajectory" --start 15)
  rm -rf "$seq"
  mkdir -p "$cache"
  "$superdyna" simulate --out "$seq" "${motion[@]}" --duration "$duration" --scene indoor \
    --dynamic none --seed "$seed" --landmarks 0 >"$cache/simulate.log" 2>&1
fi
out=$(mktemp -d "${TMPDIR:-/tmp}/superdyna_fps.XXXXXX")
printf "| pipeline | frames | wall FPS | CPU-bound FPS | extract | stereo | track | kf + local BA | thread CPU s (front end + helper / tracking / mapping) | ATE RMSE |\n"
printf "|---|---|---|---|---|---|---|---|---|---|\n"
for mode in $modes; do
  flag=()
  [ "$mode" = deterministic ] && flag=(--deterministic)
  log=$out/$mode.log
  "$superdyna" run --dataset euroc --path "$seq" --mode stereo-inertial \
    --config "$config" --output "$out/$mode.txt" "${flag[@]}" "${run_args[@]}" \
    >"$log" 2>&1 || { echo "$mode run failed, see $log" >&2; exit 1; }
  awk -v mode="$mode" '
    /^[0-9]+ frames in/ { frames = $1; fps = $6; gsub(/[(]/, "", fps) }
    /^timing per frame/ {
      for (i = 1; i <= NF; ++i) {
        v = $(i + 1); gsub(/,/, "", v)
        if ($i == "extract") ex = v; if ($i == "stereo") st = v; if ($i == "track") tr = v
        if ($i == "BA") ba = v
      }
    }
    /^pipeline: deterministic/ {
      for (i = 1; i <= NF; ++i) { if ($i == "CPU") cpu = $(i + 2); if ($i == "helper") hp = $(i + 1) }
      fe = cpu - hp; tk = "-"; mp = "-"
      m = fe; if (cpu / 2 > m) m = cpu / 2
      bound = frames / m
    }
    /^pipeline: concurrent/ {
      for (i = 1; i <= NF; ++i) {
        if ($i == "end") fe = $(i + 1); if ($i == "helper") hp = $(i + 1)
        if ($i == "tracking") tk = $(i + 1); if ($i == "mapping") mp = $(i + 1)
      }
      m = fe; if (hp > m) m = hp; if (tk > m) m = tk; if (mp > m) m = mp
      if ((fe + hp + tk + mp) / 2 > m) m = (fe + hp + tk + mp) / 2
      bound = frames / m
    }
    /^ATE/ { ate = $5 }
    END { printf "| %s | %d | %.1f | %.1f | %s ms | %s ms | %s ms | %s ms | %.1f + %.1f / %s / %s | %s m |\n",
                 mode, frames, fps, bound, ex, st, tr, ba, fe, hp, tk, mp, ate }' "$log"
done
echo
echo "config $config${RUN_ARGS:+, run options $RUN_ARGS}"
echo "sequence $seq; logs in $out; $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg)"

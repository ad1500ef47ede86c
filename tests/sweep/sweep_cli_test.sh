#!/usr/bin/env bash
# End to end, `superdyna sweep` on two short simulated sequences (street, indoor) x three configs
# (ORB stereo, ORB stereo-inertial, and a script standing in for an external peer that writes
# ORB-SLAM3's EuRoC output: TUM rows with nanosecond times), deterministic:
#  1. killed with SIGKILL once two cells have finished, then started again: the children died
#     with it, the finished cells are not run again (their result.json is unchanged) and the
#     sweep ends with every cell ok;
#  2. the peer is scored in the same ATE table as our configs; the stereo-inertial config's
#     moving-object decisions are scored against the simulator's truth;
#  3. the HTML report opens in headless Chromium with no script error and every image loaded
#     (the page's own check, <body data-status="ok N images">);
#  4. GNU parallel dispatch runs every cell (its job log) and scores the peer as the local run did;
#  5. with a Slurm cluster (the third argument "slurm"): the same spec dispatched as Slurm job
#     arrays to a single-node cluster on this machine (scripts/slurm_local_cluster.sh) gives
#     accuracy tables identical to the local run's.
# Usage: sweep_cli_test.sh SUPERDYNA REPO [slurm]
set -euo pipefail
superdyna=$1
repo=$2
mode=${3:-local}
work=$(mktemp -d)
cluster=""
cleanup() {
  if [ -n "$cluster" ]; then "$repo/scripts/slurm_local_cluster.sh" stop "$cluster" || true; fi
  rm -rf "$work"
}
trap cleanup EXIT
fail() {
  echo "FAIL: $*"
  exit 1
}

cat >"$work/peer.sh" <<'EOF'
#!/bin/sh
# Stand-in for an external SLAM system: the ground truth with a slow drift along x (1 mm per
# pose), written as ORB-SLAM3 writes EuRoC runs (TUM layout, times in nanoseconds).
awk -F, 'NR > 1 && NR % 10 == 0 { n++; printf "%s.000000 %.6f %s %s %s %s %s %s\n", $1, $2 + 0.001 * n, $3, $4, $6, $7, $8, $5 }' "$1" >"$2"
EOF
chmod +x "$work/peer.sh"
cat >"$work/spec.yaml" <<EOF
name: e2e
runs: 1
sequences:
  - {name: street, simulate: [--scene, street, --dynamic, mid, --duration, "4", --seed, "21"]}
  - {name: indoor, simulate: [--scene, indoor, --dynamic, none, --duration, "4", --seed, "5"]}
configs:
  - {name: orb-stereo, mode: stereo, config: $repo/configs/euroc_stereo.yaml}
  - {name: orb-si, mode: stereo-inertial, config: $repo/configs/euroc_stereo_inertial.yaml,
     args: [--instance-masks, --dynamic, semantic-geometric, --overlay, "{out}/overlay",
            --overlay-every, "20"]}
  - {name: peer, command: "$work/peer.sh {gt} {out}/peer.txt", trajectory: "{out}/peer.txt",
     trajectory_format: tum, time_unit: ns}
tables:
  - {name: ablation, title: "configs as rows", metric: ate_median, rows: configs}
EOF

finished_cells() { find "$1/cells" -name result.json 2>/dev/null | wc -l; }

echo "-- 1. kill the sweep once two cells have finished, then start it again"
"$superdyna" sweep "$work/spec.yaml" --out "$work/local" -j 2 >"$work/first.log" 2>&1 &
sweep_pid=$!
for _ in $(seq 1 600); do
  [ "$(finished_cells "$work/local")" -ge 2 ] && break
  kill -0 "$sweep_pid" 2>/dev/null || break
  sleep 0.5
done
[ "$(finished_cells "$work/local")" -ge 2 ] || { cat "$work/first.log"; fail "no two cells finished"; }
kill -9 "$sweep_pid"
wait "$sweep_pid" 2>/dev/null || true
before=$(finished_cells "$work/local")
[ "$before" -lt 6 ] || fail "all cells had finished before the kill: nothing to resume"
sleep 1
if pgrep -f -- "--output $work/local/" >/dev/null; then fail "runs of the killed sweep live on"; fi
(cd "$work/local/cells" && find . -name result.json -exec md5sum {} + | sort) >"$work/done_before"
"$superdyna" sweep "$work/spec.yaml" --out "$work/local" -j 2 >"$work/second.log" 2>&1 ||
  { cat "$work/second.log"; fail "the resumed sweep failed"; }
grep -q "6 cells: $before finished before, $((6 - before)) to run" "$work/second.log" ||
  { cat "$work/second.log"; fail "the resumed sweep did not skip the $before finished cells"; }
(cd "$work/local/cells" && md5sum $(cut -d' ' -f3 "$work/done_before")) | sort >"$work/done_after"
diff "$work/done_before" "$work/done_after" || fail "a finished cell was run again"
[ "$(finished_cells "$work/local")" -eq 6 ] || fail "not every cell finished"
grep -q '"ok": false' -r "$work/local/cells" --include=result.json && fail "a cell failed"
for f in command.txt cell.json log.txt trajectory.txt stats.json eval.json pose_errors.csv; do
  [ -s "$work/local/cells/street/orb-si/run-1/$f" ] || fail "the cell has no $f"
done
grep -q '"git_revision"' "$work/local/cells/street/orb-si/run-1/cell.json" || fail "no revision"
grep -q '"cpu"' "$work/local/cells/street/orb-si/run-1/cell.json" || fail "no machine"

echo "-- 2. the peer in the same table as ours"
grep -E '^\| street \| [0-9.]+ cm \| [0-9.]+ cm \| [0-9.]+ cm \|$' "$work/local/tables/ate.md" ||
  { cat "$work/local/tables/ate.md"; fail "street: not three scored configs"; }
grep -E '^\| peer \| [0-9.]+ cm \| [0-9.]+ cm \|$' "$work/local/tables/ablation.md" ||
  { cat "$work/local/tables/ablation.md"; fail "the transposed table lacks the peer"; }
for t in accuracy speed timing; do [ -s "$work/local/tables/$t.csv" ] || fail "no $t.csv"; done
grep -E '^\| street \| orb-si \| 1 / 1 \| [0-9.]+ % \| [0-9.]+ % \| [0-9.]+ % \|$' \
  "$work/local/tables/decisions.md" ||
  { cat "$work/local/tables/decisions.md"; fail "no scored moving-object decisions"; }

echo "-- 3. the report in headless Chromium"
page=$work/local/report/index.html
chromium --headless --no-sandbox --disable-gpu --virtual-time-budget=10000 \
  --dump-dom "file://$page" >"$work/dom.html" 2>"$work/chromium.log" ||
  { cat "$work/chromium.log"; fail "chromium failed"; }
status=$(grep -o 'data-status="[^"]*"' "$work/dom.html" || true)
images=$(grep -c '<img ' "$page")
echo "report: $status ($images <img> in the page)"
[ "$status" = "data-status=\"ok $images images\"" ] || fail "the report is not complete: $status"
[ "$images" -ge 7 ] ||
  fail "expected two top views, two ATE plots, the timing bars and overlay images"

echo "-- 4. GNU parallel dispatch (the peer again, on the simulated sequences as recorded datasets)"
cat >"$work/parallel.yaml" <<EOF
name: parallel
runs: 2
sequences:
  - {name: street, path: $work/local/sequences/street}
  - {name: indoor, path: $work/local/sequences/indoor}
configs:
  - {name: peer, command: "$work/peer.sh {gt} {out}/peer.txt", trajectory: "{out}/peer.txt",
     trajectory_format: tum, time_unit: ns}
EOF
"$superdyna" sweep "$work/parallel.yaml" --out "$work/parallel" --dispatch parallel -j 2 \
  >"$work/parallel.log" 2>&1 || { cat "$work/parallel.log"; fail "the parallel sweep failed"; }
[ "$(tail -n +2 "$work/parallel/dispatch/cells.joblog" | wc -l)" -eq 4 ] ||
  fail "GNU parallel did not run the 4 cells"
peer_local=$(grep '^| street ' "$work/local/tables/ate.md" | awk -F'|' '{print $5}')
peer_parallel=$(grep '^| street ' "$work/parallel/tables/ate.md" | awk -F'|' '{print $3}')
[ "$peer_local" = "$peer_parallel" ] || fail "the peer scored $peer_parallel, locally $peer_local"

if [ "$mode" = slurm ]; then
  echo "-- 5. the same spec through a single-node Slurm cluster"
  "$repo/scripts/slurm_local_cluster.sh" install
  cluster=$work/cluster
  env_line=$("$repo/scripts/slurm_local_cluster.sh" start "$cluster")
  eval "$env_line"
  "$superdyna" sweep "$work/spec.yaml" --out "$work/slurm" --dispatch slurm >"$work/slurm.log" 2>&1 ||
    { cat "$work/slurm.log"; fail "the Slurm sweep failed"; }
  grep -q "dispatch: sbatch --wait --array=0-5" "$work/slurm.log" || fail "not dispatched to Slurm"
  ls "$work/slurm/dispatch"/cells-*.log >/dev/null || fail "no Slurm task logs"
  for t in ate accuracy ablation decisions; do
    diff "$work/local/tables/$t.md" "$work/slurm/tables/$t.md" || fail "$t differs under Slurm"
  done
  echo "Slurm and local tables identical"
fi
echo "PASS"

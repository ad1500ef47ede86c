#!/usr/bin/env bash
# Summarises the per-run rows of bench/robustness.sh (results.md of one or more OUT_DIRs): per
# sequence and config the number of runs, the median lost frames, the median ATE and the
# median match error; a run that failed to give an ATE counts as infinitely bad. Then, per
# config other than the first (the reference, ORB in the default list), on how many sequences
# it has both fewer median lost frames (or equally none) and a lower median ATE than the first.
# Usage: bench/robustness_summary.sh RESULTS.md [RESULTS.md ...]
set -euo pipefail
if [ $# -lt 1 ]; then
  sed -n '2,7p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
  exit 1
fi
for f in "$@"; do
  [ -f "$f" ] || { echo "$f: no such file" >&2; exit 2; }
done
awk -F'|' '
  function trim(s) { gsub(/^ +| +$/, "", s); return s }
  function median(list,   n, a, i, j, t) {
    n = split(list, a, " ")
    for (i = 2; i <= n; i++) { t = a[i]; for (j = i - 1; j >= 1 && a[j] + 0 > t + 0; j--) a[j + 1] = a[j]; a[j + 1] = t }
    if (n % 2) return a[(n + 1) / 2]
    return (a[n / 2] + a[n / 2 + 1]) / 2
  }
  /^\| *(sequence|---)/ { next }
  /^\|/ {
    seq = trim($2); config = trim($4); lost = trim($5); ate = trim($7); match_px = trim($8)
    split(lost, l, "/"); lost = trim(l[1]); if (lost == "") lost = 1e9
    if (ate == "") ate = 1e9
    if (match_px == "") match_px = 1e9
    key = seq SUBSEP config
    if (!(key in n)) { n[key] = 0; if (!(seq in seen)) { seen[seq] = 1; seqs[++ns] = seq } if (!(config in cseen)) { cseen[config] = 1; configs[++nc] = config } }
    n[key]++; L[key] = L[key] " " lost; A[key] = A[key] " " ate; M[key] = M[key] " " match_px
  }
  END {
    print "| sequence | config | runs | lost frames (median) | ATE RMSE [m] (median) | match median [px] (median) |"
    print "|---|---|---|---|---|---|"
    for (s = 1; s <= ns; s++) for (c = 1; c <= nc; c++) {
      key = seqs[s] SUBSEP configs[c]; if (!(key in n)) continue
      ml[key] = median(L[key]); ma[key] = median(A[key])
      printf "| %s | %s | %d | %s | %s | %s |\n", seqs[s], configs[c], n[key], ml[key], (ma[key] >= 1e9 ? "failed" : ma[key]), median(M[key])
    }
    print ""
    for (c = 2; c <= nc; c++) {
      wins = 0; total = 0
      for (s = 1; s <= ns; s++) {
        ref = seqs[s] SUBSEP configs[1]; key = seqs[s] SUBSEP configs[c]
        if (!(ref in n) || !(key in n)) continue
        total++
        if ((ml[key] < ml[ref] || (ml[key] == 0 && ml[ref] == 0)) && ma[key] < ma[ref]) wins++
      }
      printf "%s against %s: fewer lost frames (or none) and lower median ATE on %d of %d sequences\n", configs[c], configs[1], wins, total
    }
  }' "$@"

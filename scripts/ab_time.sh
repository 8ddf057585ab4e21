#!/usr/bin/env bash
# Times two commands in turn (A B A B ...) with GNU time and prints, per command, the median
# whole-process wall, user + system CPU and peak memory, and the median of the pair-by-pair
# ratios A / B. Taking the runs in turn keeps the ratio meaningful on a machine whose speed
# drifts (docs/performance.md quotes only such ratios when the machine was shared).
#
#   scripts/ab_time.sh [-n PAIRS] "COMMAND A" "COMMAND B"
#
# Example (a new build against an old one):
#   scripts/ab_time.sh -n 3 "build/bin/mpm bench --particles 1000000 --cases jello --threads 2" \
#     "/tmp/old_mpm bench --particles 1000000 --cases jello --threads 2"
set -euo pipefail

pairs=3
if [ "${1:-}" = "-n" ]; then
  pairs=$2
  shift 2
fi
if [ $# -ne 2 ] || ! [[ "$pairs" =~ ^[1-9][0-9]*$ ]]; then
  echo "usage: scripts/ab_time.sh [-n PAIRS] \"COMMAND A\" \"COMMAND B\"" >&2
  exit 2
fi
[ -x /usr/bin/time ] || { echo "ab_time.sh: needs GNU time (apt-get install time)" >&2; exit 2; }

log=$(mktemp)
trap 'rm -f "$log" "$log.t"' EXIT
for ((i = 1; i <= pairs; ++i)); do
  for side in A B; do
    cmd=$1
    [ "$side" = B ] && cmd=$2
    # wall s, user s, system s, peak KiB; the command's own output is dropped.
    /usr/bin/time -o "$log.t" -f "%e %U %S %M" bash -c "$cmd" > /dev/null 2>&1 ||
      { echo "ab_time.sh: '$cmd' failed" >&2; exit 1; }
    echo "$side $i $(tail -n 1 "$log.t")" >> "$log"
  done
done

awk -v pairs="$pairs" '
  function median(a, n,    i, j, t) {
    for (i = 2; i <= n; ++i) for (j = i; j > 1 && a[j - 1] > a[j]; --j) { t = a[j]; a[j] = a[j - 1]; a[j - 1] = t }
    return n % 2 ? a[(n + 1) / 2] : (a[n / 2] + a[n / 2 + 1]) / 2
  }
  { wall[$1, $2] = $3; cpu[$1, $2] = $4 + $5; peak[$1, $2] = $6 / 1024 }
  END {
    for (s = 0; s < 2; ++s) {
      side = s ? "B" : "A"
      for (i = 1; i <= pairs; ++i) { w[i] = wall[side, i]; c[i] = cpu[side, i]; m[i] = peak[side, i] }
      printf "%s: wall %.3f s, cpu %.3f s, peak %.1f MiB (medians of %d)\n", side, median(w, pairs), median(c, pairs), median(m, pairs), pairs
    }
    for (i = 1; i <= pairs; ++i) { rw[i] = wall["A", i] / wall["B", i]; rc[i] = cpu["A", i] / cpu["B", i] }
    printf "A/B: wall %.3f, cpu %.3f (medians of the pair-by-pair ratios)\n", median(rw, pairs), median(rc, pairs)
  }' "$log"

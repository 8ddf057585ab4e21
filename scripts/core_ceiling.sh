#!/usr/bin/env bash
# How much of a second core this machine can give a workload, against how much the engine
# takes: runs `mpm bench ARGS --threads 1` alone on each core, then two copies at once (one per
# core, independent processes that share nothing but the machine), then `--threads 2`, and
# prints each stage's ns per particle-step and two ratios per stage:
#   ceiling = 2 x (alone) / (together): the 2-thread speed-up the machine allows if the
#             threads slowed each other only as much as two independent processes do;
#   engine  = (alone) / (2 threads): the speed-up the engine gets.
# A stage whose engine ratio is near its ceiling is limited by what the cores share (caches,
# memory), not by serial work or imbalance in the engine. Rounds repeat the four runs in turn.
#
#   scripts/core_ceiling.sh [-n ROUNDS] [-b MPM] -- BENCH ARGS...
#
# Example (the 1M two_cubes of issue 32):
#   scripts/core_ceiling.sh -n 2 -- scenes/two_cubes.yaml --set grid.dims=170 \
#     --set simulation.dt=0.0005 --frames 5
set -euo pipefail

usage() { echo "usage: scripts/core_ceiling.sh [-n ROUNDS] [-b MPM] -- BENCH ARGS..." >&2; exit 2; }
rounds=1
mpm=build/bin/mpm
while [ $# -gt 0 ] && [ "$1" != "--" ]; do
  case "$1" in
    -n) [ $# -ge 2 ] || usage; rounds=$2; shift 2 ;;
    -b) [ $# -ge 2 ] || usage; mpm=$2; shift 2 ;;
    *) usage ;;
  esac
done
[ "${1:-}" = "--" ] && shift
{ [ $# -gt 0 ] && [[ "$rounds" =~ ^[1-9][0-9]*$ ]]; } || usage
[ "$(nproc)" -ge 2 ] || { echo "core_ceiling.sh: needs two cores" >&2; exit 2; }
command -v taskset > /dev/null || { echo "core_ceiling.sh: needs taskset (util-linux)" >&2; exit 2; }

dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
# The stage line of one bench run: "name: stage ns stage ns ...".
stages() { grep -E '^[^ ]+: sort ' "$1" | tail -n 1 | cut -d: -f2; }
run() {  # run LOG CORES THREADS
  taskset -c "$2" "$mpm" bench "${@:4}" --threads "$3" > "$1" 2>&1 ||
    { cat "$1" >&2; echo "core_ceiling.sh: mpm bench failed" >&2; exit 1; }
}
for ((r = 1; r <= rounds; ++r)); do
  run "$dir/alone0" 0 1 "$@"
  run "$dir/alone1" 1 1 "$@"
  run "$dir/together0" 0 1 "$@" &
  pid=$!
  run "$dir/together1" 1 1 "$@"
  wait "$pid"
  run "$dir/two" 0,1 2 "$@"
  for f in alone0 alone1 together0 together1 two; do echo "$r $f $(stages "$dir/$f")"; done
done > "$dir/table"

awk '
  { for (i = 3; i < NF; i += 2) { t[$1, $2, $i] = $(i + 1); if (!($i in seen)) { seen[$i] = 1; order[++n] = $i } } rounds = $1 }
  END {
    printf "%-18s %8s %8s %8s %8s %8s\n", "stage (ns)", "alone", "together", "2 threads", "ceiling", "engine"
    for (k = 1; k <= n + 1; ++k) {
      s = k <= n ? order[k] : "sum"
      a = b = c = 0
      for (r = 1; r <= rounds; ++r) {
        if (s == "sum") {
          for (j = 1; j <= n; ++j) {
            a += (t[r, "alone0", order[j]] + t[r, "alone1", order[j]]) / 2
            b += (t[r, "together0", order[j]] + t[r, "together1", order[j]]) / 2
            c += t[r, "two", order[j]]
          }
        } else {
          a += (t[r, "alone0", s] + t[r, "alone1", s]) / 2
          b += (t[r, "together0", s] + t[r, "together1", s]) / 2
          c += t[r, "two", s]
        }
      }
      a /= rounds; b /= rounds; c /= rounds
      if (a < 0.5 && s != "sum") continue
      printf "%-18s %8.1f %8.1f %8.1f %7.2fx %7.2fx\n", s, a, b, c, (b > 0 ? 2 * a / b : 0), (c > 0 ? a / c : 0)
    }
    printf "(means over %d round(s); alone and together: the mean of the two cores)\n", rounds
  }' "$dir/table"

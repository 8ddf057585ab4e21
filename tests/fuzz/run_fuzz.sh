#!/usr/bin/env bash
# Builds the scene-loader fuzzer (clang libFuzzer, ASan + UBSan) in its own build folder, runs
# it once over every input in tests/fuzz/regressions/, then fuzzes for SECONDS seconds from the
# scenes in scenes/. Exits non-zero on any crash, leak, hang, sanitizer report or build error,
# and prints the input that caused it.
#
# Usage: tests/fuzz/run_fuzz.sh SOURCE_DIR [SECONDS]
# Environment: MPM_FUZZ_BUILD_DIR  build folder (default SOURCE_DIR/build-fuzz; never build/)
#              MPM_FUZZ_JOBS       parallel compile jobs (default: nproc)
set -euo pipefail

src=$(cd "${1:?usage: run_fuzz.sh SOURCE_DIR [SECONDS]}" && pwd)
seconds=${2:-60}
build=${MPM_FUZZ_BUILD_DIR:-$src/build-fuzz}
jobs=${MPM_FUZZ_JOBS:-$(nproc)}
here=$src/tests/fuzz
say() { echo "run_fuzz: $*"; }

# clang from the `clang` package, or clang-14 as scripts/install-deps.sh installs it.
cc=$(command -v clang || command -v clang-14 || true)
cxx=$(command -v clang++ || command -v clang++-14 || true)
if [ -z "$cc" ] || [ -z "$cxx" ]; then
  say "clang not found (scripts/install-deps.sh installs clang-14)"
  exit 1
fi

# Build.
start=$SECONDS
mkdir -p "$build"
say "building fuzz_scene in $build (ASan + UBSan, $jobs jobs)"
if ! CC=$cc CXX=$cxx cmake -S "$src" -B "$build" -DMPM_FUZZ=ON \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo > "$build/configure.log" 2>&1; then
  cat "$build/configure.log"
  say "FAILED: configure"
  exit 1
fi
if ! cmake --build "$build" --target fuzz_scene --parallel "$jobs" > "$build/build.log" 2>&1; then
  tail -n 60 "$build/build.log"
  say "FAILED: build (full log: $build/build.log)"
  exit 1
fi
say "built in $((SECONDS - start)) s"
fuzzer=$build/bin/fuzz_scene

# Sanitizer settings: stop at the first report, with a symbolized stack.
symbolizer=$(command -v llvm-symbolizer-14 || command -v llvm-symbolizer || true)
if [ -n "$symbolizer" ]; then export ASAN_SYMBOLIZER_PATH=$symbolizer; fi
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1:symbolize=1}
asan_full=${ASAN_OPTIONS:-detect_leaks=1:symbolize=1}
# While fuzzing, allocation stacks of two frames only: ASan keeps every distinct stack forever,
# and allocations in the uninstrumented yaml-cpp give ever new ones (RSS grew ~1.5 MB/s with
# the default 30). Not fewer: LeakSanitizer counts a block without a caller frame as reachable,
# so it would find no leak at all. Failures are replayed with full stacks.
asan_fuzz=${ASAN_OPTIONS:-$asan_full:malloc_context_size=2}

artifacts=$build/fuzz-artifacts
corpus=$build/fuzz-corpus
rm -rf "$artifacts" "$corpus"
mkdir -p "$artifacts" "$corpus"
common=(-timeout=10 -rss_limit_mb=2048 -detect_leaks=1 -artifact_prefix="$artifacts/")

# Prints the end of the report and each failing input (hex and text), then fails. Without
# INPUTS: the inputs libFuzzer saved, each replayed with full allocation stacks.
report_failure() {
  local what=$1 log=$2 input
  local inputs=("${@:3}")
  if [ ${#inputs[@]} -eq 0 ]; then
    inputs=("$artifacts"/*)
    echo "----- what $log says -----"
    grep -E "ERROR|SUMMARY|runtime error|fuzz_scene: |Done [0-9]+ runs|Test unit written" "$log" |
      tail -n 20
  else
    echo "----- end of $log -----"
    tail -n 80 "$log"
  fi
  for input in "${inputs[@]}"; do
    [ -f "$input" ] || continue
    echo "-----"
    say "input that fails: $input ($(wc -c < "$input") bytes)"
    od -A d -t x1z -v "$input" | head -n 64
    echo "----- as text -----"
    head -c 4000 "$input" | cat -v
    echo
    if [ $# -eq 2 ]; then
      echo "----- replayed with full allocation stacks -----"
      ASAN_OPTIONS=$asan_full "$fuzzer" "${common[@]}" "$input" 2>&1 | tail -n 80 || true
    fi
  done
  echo "-----"
  say "FAILED: $what; reproduce with: $fuzzer INPUT"
  exit 1
}

# 1. Every regression input once (libFuzzer runs files given as arguments and exits).
regressions=()
if [ -d "$here/regressions" ]; then
  mapfile -t regressions < <(find "$here/regressions" -type f | sort)
fi
if [ ${#regressions[@]} -gt 0 ]; then
  log=$build/fuzz-regressions.log
  if ! ASAN_OPTIONS=$asan_full "$fuzzer" "${common[@]}" "${regressions[@]}" > "$log" 2>&1; then
    last=$(sed -n 's/^Running: //p' "$log" | tail -n 1)
    report_failure "a regression input fails again" "$log" "$last"
  fi
  say "${#regressions[@]} regression inputs pass"
  cp "${regressions[@]}" "$corpus/"
fi

# 2. Fuzz from the seed scenes: every scene under scenes/ (scenes/stress/x.yaml -> stress_x.yaml).
while IFS= read -r scene; do
  rel=${scene#"$src"/scenes/}
  cp "$scene" "$corpus/${rel//\//_}"
done < <(find "$src/scenes" -name '*.yaml' | sort)
seeds=$(find "$corpus" -type f | wc -l)
log=$build/fuzz.log
say "fuzzing for $seconds s from $seeds seeds (log: $log)"
status=0
ASAN_OPTIONS=$asan_fuzz "$fuzzer" "${common[@]}" -max_total_time="$seconds" \
  -dict="$here/scene.dict" -print_final_stats=1 "$corpus" > "$log" 2>&1 || status=$?
if [ "$status" -ne 0 ]; then report_failure "fuzz_scene exited with status $status" "$log"; fi
if grep -q -E "^(==[0-9]+==ERROR|SUMMARY: )|runtime error:" "$log"; then
  report_failure "a sanitizer report in the log" "$log"
fi

runs=$(sed -n 's/^Done \([0-9]*\) runs in \([0-9]*\) second.*/\1 runs in \2 s/p' "$log" | tail -n 1)
size=$(find "$corpus" -type f | wc -l)
say "OK: ${runs:-? runs}, no crash, leak or hang; corpus $size inputs ($seeds seeds)," \
  "${#regressions[@]} regression inputs; total $((SECONDS - start)) s"

#!/usr/bin/env bash
# Runs the libFuzzer targets of tools/fuzz on a seed corpus made from experiments/ and
# tests/io/malformed/ (docs/fuzzing.md). Needs the sanitize build:
#   cmake --preset sanitize && cmake --build --preset sanitize --target fuzz_scene fuzz_run
#
#   bash tools/fuzz/run.sh SECONDS [TARGET ...]       # default targets: fuzz_scene fuzz_run
#   FUZZ_RUNS=1000000 bash tools/fuzz/run.sh 0 fuzz_scene  # a number of executions instead (0 s: no time limit)
#
# Each target runs SECONDS of wall time on one core (inputs up to MAX_LEN bytes, default 4096), from the seeds plus what earlier runs kept
# in build/sanitize/fuzz/corpus-TARGET. Exit status: 0 if no target found anything; else 1, with
# the crashing input saved as build/sanitize/fuzz/TARGET-crash-* (turn it into a malformed-scene
# test: tests/io/malformed/, docs/fuzzing.md).
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${1:?usage: run.sh SECONDS [TARGET ...]}
shift
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(fuzz_scene fuzz_run)
build=build/sanitize
work=$build/fuzz
mkdir -p "$work/seeds"
find experiments tests/io/malformed tools/fuzz/regressions -name '*.yaml' -size -64k -exec cp {} "$work/seeds/" \;
status=0
for target in "${targets[@]}"; do
  corpus=$work/corpus-$target
  mkdir -p "$corpus"
  echo "fuzz: $target for $seconds s (corpus $corpus, seeds $work/seeds)" >&2
  if ! ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
      LSAN_OPTIONS=suppressions=$PWD/tools/fuzz/lsan.supp \
      "$build/tools/fuzz/$target" "$corpus" "$work/seeds" -dict=tools/fuzz/scene.dict \
      -max_total_time="$seconds" ${FUZZ_RUNS:+-runs="$FUZZ_RUNS"} -max_len="${MAX_LEN:-4096}" -timeout=30 -rss_limit_mb=4096 -malloc_limit_mb=4096 \
      -artifact_prefix="$work/$target-" -print_final_stats=1 > "$work/$target.log" 2>&1; then
    status=1
    echo "fuzz: $target FOUND A PROBLEM (log: $work/$target.log):" >&2
    grep -E "ERROR|SUMMARY|runtime error|Test unit written" "$work/$target.log" | head -20 >&2
  fi
  grep -E "stat::number_of_executed_units|stat::peak_rss_mb" "$work/$target.log" | sed "s/^/fuzz: $target: /" >&2
done
exit $status

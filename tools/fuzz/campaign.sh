#!/usr/bin/env bash
# A fuzz campaign: each libFuzzer target of tools/fuzz runs a fixed number of executions from the
# seed corpus, both at once (one core each), and the figures docs/fuzzing.md records are written
# to a log and printed as table rows (docs/fuzzing.md, "Record").
#
#   bash tools/fuzz/campaign.sh [-n RUNS] [-t SECONDS] [-b BUILD] [-w WORK] [TARGET ...]
#
#   -n RUNS   executions per target (libFuzzer -runs), default 1000000
#   -t SECONDS  at most this wall time per target (libFuzzer -max_total_time), default none
#   -b BUILD  the build whose tools/fuzz/TARGET binaries run, default build/fuzz (the `fuzz` preset:
#             UBSan, no ASan, -O2: cmake --preset fuzz && cmake --build --preset fuzz); build/sanitize
#             for ASan + UBSan at -O1 (cmake --build --preset sanitize --target fuzz_scene fuzz_run),
#             several times slower (docs/fuzzing.md). The log and the table rows name the build's
#             sanitizers and optimisation. Only read: nothing is written there unless WORK lies inside it
#   -w WORK   where the campaign writes (created; it must not exist or be empty), default
#             BUILD/fuzz-campaign-DATE: seeds/, corpus-TARGET/ (what the run learnt),
#             TARGET.log (libFuzzer's output), TARGET-crash-* etc. (findings), campaign.log
#   TARGET    default: fuzz_scene fuzz_run
#
# The seeds are those of run.sh (every scene of experiments/, tests/io/malformed/ and
# tools/fuzz/regressions/), with tools/fuzz/scene.dict; the limits too (inputs up to MAX_LEN
# bytes, default 4096; 30 s per input; 4 GB). Each target is started fresh from the seeds (not
# from a corpus an earlier run kept), so a campaign's figures are its own. NICE (default 0) is
# the niceness the targets run at.
#
# Per target the log records: executions, wall time, exec/s, coverage (libFuzzer's cov: edges and
# ft: features at the end, and the corpus it kept), peak RSS, the slowest input, and what it found
# (libFuzzer stops at its first finding: a crash, a sanitizer report, a timeout, an out-of-memory;
# the input is kept as WORK/TARGET-KIND-HASH). Inputs slower than 10 s are kept too
# (TARGET-slow-unit-*) and counted, but are no finding: on a loaded machine they are the load's.
# Exit status: 0 if no target found anything, else 1.
set -euo pipefail
cd "$(dirname "$0")/../.."
source=$PWD
runs=1000000
seconds=0
build=build/fuzz
work=
while getopts "n:t:b:w:" option; do
  case $option in
    n) runs=$OPTARG ;;
    t) seconds=$OPTARG ;;
    b) build=$OPTARG ;;
    w) work=$OPTARG ;;
    *) sed -n '5,18p' "$0" >&2; exit 2 ;;
  esac
done
shift $((OPTIND - 1))
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(fuzz_scene fuzz_run)
case $runs in '' | *[!0-9]*) echo "campaign: -n $runs: not a whole number of executions" >&2; exit 2 ;; esac
case $seconds in '' | *[!0-9]*) echo "campaign: -t $seconds: not a whole number of seconds" >&2; exit 2 ;; esac
[ -d "$build" ] || { echo "campaign: no build folder $build (the campaign build: cmake --preset fuzz && cmake --build --preset fuzz; or -b build/sanitize)" >&2; exit 2; }
build=$(cd "$build" && pwd)
for target in "${targets[@]}"; do
  [ -x "$build/tools/fuzz/$target" ] || { echo "campaign: $build/tools/fuzz/$target is missing (build it: cmake --build --preset fuzz, or --preset sanitize --target $target)" >&2; exit 2; }
done
work=${work:-$build/fuzz-campaign-$(date -u +%Y%m%dT%H%M%SZ)}
if [ -e "$work" ] && [ -n "$(ls -A "$work")" ]; then
  echo "campaign: $work exists and is not empty: give a new folder (-w)" >&2
  exit 2
fi
mkdir -p "$work/seeds"
work=$(cd "$work" && pwd)
find experiments tests/io/malformed tools/fuzz/regressions -name '*.yaml' -size -64k -exec cp {} "$work/seeds/" \;
seeds=$(find "$work/seeds" -type f | wc -l)

# What was fuzzed: the commit of the build's sources (and whether its tree differed from it).
tree=$(sed -n 's/^CMAKE_HOME_DIRECTORY:INTERNAL=//p' "$build/CMakeCache.txt" 2>/dev/null || true)
commit=unknown
if [ -n "$tree" ] && git -C "$tree" rev-parse --short HEAD > /dev/null 2>&1; then
  commit=$(git -C "$tree" rev-parse --short HEAD)
  git -C "$tree" diff --quiet HEAD -- 2> /dev/null || commit="$commit (with uncommitted changes)"
fi
# Which instrumentation the binaries carry, from the build's cache: "ASan + UBSan, -O1" or "UBSan, -O2".
cache() { sed -n "s/^$1:[A-Z]*=//p" "$build/CMakeCache.txt" 2>/dev/null | head -1; }
flags="$(cache CMAKE_CXX_FLAGS) $(cache "CMAKE_CXX_FLAGS_$(cache CMAKE_BUILD_TYPE | tr a-z A-Z)")"
sanitizers=$(grep -o -- '-fsanitize=[a-z,-]*' <<< "$flags" | sed 's/-fsanitize=//' | tr ',' '\n' | sed -n 's/^address$/ASan/p; s/^undefined$/UBSan/p' | sort -u | paste -sd+ | sed 's/+/ + /g')
optimisation=$(grep -o -- '-O[0-3s]' <<< "$flags" | tail -1)
instrumented="${sanitizers:-no sanitizer}, ${optimisation:-?}"
log=$work/campaign.log
{
  echo "campaign: $(date -u '+%Y-%m-%d %H:%M:%S UTC'), $runs executions per target$([ "$seconds" = 0 ] || echo " (at most $seconds s each)"), ${#targets[@]} target(s) at once"
  echo "build: $build, $instrumented (sources $tree at $commit; binaries of $(date -u -r "$build/tools/fuzz/${targets[0]}" '+%Y-%m-%d %H:%M UTC'))"
  echo "seeds: $seeds scenes; dictionary tools/fuzz/scene.dict; max_len ${MAX_LEN:-4096}; machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
} | tee "$log" >&2

declare -A pid started
for target in "${targets[@]}"; do
  mkdir -p "$work/corpus-$target"
  started[$target]=$(date +%s.%N)
  # The subshell's `times` gives the target's CPU time (every thread's), which a loaded machine
  # does not stretch as it stretches the wall time. fuzz_run writes its per-input phase times
  # (FUZZ_RUN_TIMES, tools/fuzz/fuzz_run.cpp) to WORK/TARGET.times.
  ( cd "$work" || exit 2
    code=0
    nice -n "${NICE:-0}" env ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=1 \
      UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 LSAN_OPTIONS=suppressions=$source/tools/fuzz/lsan.supp \
      FUZZ_RUN_TIMES="$work/$target.times" \
      "$build/tools/fuzz/$target" "$work/corpus-$target" "$work/seeds" -dict="$source/tools/fuzz/scene.dict" \
      -runs="$runs" -max_total_time="$seconds" -max_len="${MAX_LEN:-4096}" -timeout=30 -rss_limit_mb=4096 -malloc_limit_mb=4096 \
      -artifact_prefix="$work/$target-" -print_final_stats=1 > "$work/$target.log" 2>&1 || code=$?
    times > "$work/$target.cpu"  # (not in a pipe: a pipe's subshell has no children)
    exit $code ) &
  pid[$target]=$!
done

# Ctrl-C or SIGTERM stops the targets (libFuzzer prints its final figures) and the summary follows.
trap 'for t in "${targets[@]}"; do kill -INT "${pid[$t]}" 2> /dev/null || true; done' INT TERM
status=0
declare -A code ended
for target in "${targets[@]}"; do
  while true; do  # wait returns early when a trapped signal comes: wait again until it ends
    if wait "${pid[$target]}"; then code[$target]=0; else code[$target]=$?; fi
    kill -0 "${pid[$target]}" 2> /dev/null || break
  done
  ended[$target]=$(date +%s.%N)
done

stat() { sed -n "s/^stat::$1: *//p" "$work/$2.log" | tail -1; }
rows=()
together="both targets at once"
[ ${#targets[@]} -gt 1 ] || together="one target alone"
for target in "${targets[@]}"; do
  out=$work/$target.log
  executed=$(stat number_of_executed_units "$target")
  wall=$(awk -v a="${started[$target]}" -v b="${ended[$target]}" 'BEGIN { printf "%.0f", b - a }')
  per_second=$(awk -v n="${executed:-0}" -v s="$wall" 'BEGIN { printf "%.0f", (s > 0 ? n / s : 0) }')
  # `times`' children line: "XmY.YYYs XmY.YYYs" (user, system).
  cpu=$(tail -1 "$work/$target.cpu" 2> /dev/null | awk '{ s = 0; for (i = 1; i <= 2; ++i) { split($i, p, /[ms]/); s += 60 * p[1] + p[2] } printf "%.0f", s }' || true)
  per_cpu=$(awk -v n="${executed:-0}" -v s="${cpu:-0}" 'BEGIN { printf "%.0f", (s > 0 ? n / s : 0) }')
  # libFuzzer's last status line: "#N DONE cov: C ft: F corp: U/S ..." (or the last line before a finding).
  last=$(grep -E '^#[0-9]+.*cov: ' "$out" | tail -1 || true)
  cov=$(sed -n 's/.*cov: \([0-9]*\).*/\1/p' <<< "$last")
  ft=$(sed -n 's/.*ft: \([0-9]*\).*/\1/p' <<< "$last")
  corp=$(sed -n 's/.*corp: \([0-9]*\).*/\1/p' <<< "$last")
  slowest=$(stat slowest_unit_time_sec "$target")
  rss=$(stat peak_rss_mb "$target")
  # Slow inputs (libFuzzer keeps those above 10 s as TARGET-slow-unit-*) are noted, not findings.
  slow=$(find "$work" -maxdepth 1 -name "$target-slow-unit-*" -type f | wc -l)
  artifacts=$(find "$work" -maxdepth 1 -name "$target-*" -type f ! -name "$target-slow-unit-*" | sort)
  # libFuzzer exits 72 when it is interrupted (Ctrl-C, SIGTERM): stopped, no finding.
  if { [ "${code[$target]}" = 0 ] || [ "${code[$target]}" = 72 ]; } && [ -z "$artifacts" ]; then
    notes=()
    [ "${code[$target]}" = 0 ] || notes+=("stopped by a signal")
    [ "$slow" = 0 ] || notes+=("$slow inputs slower than 10 s kept as $target-slow-unit-*, the slowest ${slowest:-?} s")
    found=nothing
    [ ${#notes[@]} = 0 ] || found="nothing ($(IFS=';'; echo "${notes[*]}" | sed 's/;/; /g'))"
  else
    status=1
    what=$(grep -m1 -E 'ERROR: (libFuzzer|AddressSanitizer|LeakSanitizer|UndefinedBehaviorSanitizer)|runtime error|SUMMARY' "$out" || true)
    found="${what:-exit code ${code[$target]}}; input: $(echo $artifacts | tr ' ' ',')"
  fi
  {
    echo "$target: executions ${executed:-?} of $runs, wall ${wall} s, ${per_second} exec/s, CPU ${cpu:-?} s (${per_cpu} executions per CPU second), coverage cov ${cov:-?} ft ${ft:-?} (corpus ${corp:-?} inputs), peak RSS ${rss:-?} MB, slowest input ${slowest:-?} s, exit code ${code[$target]}"
    echo "$target: found: $found"
    if [ -s "$work/$target.times" ]; then  # where fuzz_run's time went (per run kind and phase)
      python3 "$source/tools/fuzz/times.py" "$work/$target.times" | sed "s/^/$target: /" || true
    fi
  } | tee -a "$log" >&2
  rows+=("| $(date -u +%Y-%m-%d) | $target | \`campaign.sh -n $runs$([ "$seconds" = 0 ] || echo " -t $seconds")\` ($instrumented; at $commit; $together) | ${executed:-?} | $wall | $per_second ($per_cpu per CPU s) | cov ${cov:-?}, ft ${ft:-?} | $found |")
done
{
  echo
  echo "| date | target | command | executions | wall s | exec/s | coverage | found |"
  echo "|---|---|---|---:|---:|---:|---|---|"
  printf '%s\n' "${rows[@]}"
} | tee -a "$log"
echo "campaign: log $log" >&2
exit $status

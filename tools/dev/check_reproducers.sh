#!/usr/bin/env bash
# Runs every reproducer of a folder of reproducers (one folder each: scenes *.yaml run as
# `vibro run SCENE -o out.h5`, Python scripts *.py run with the build's module) and checks
# that each ends the way the command promises (tools/vibro/main.cpp's exit codes):
#  * no death by a signal, no exit code 5 (an internal error);
#  * a run still going after LIMIT seconds (default 10) has said so first (stderr: a warning
#    with the work it needs, or progress lines), and on SIGTERM exits within 2 s with 130 and
#    no result file;
#  * any other failure is exit code 1–4 with an "error:" line on stderr, and leaves no
#    result file; success (0) leaves one;
#  * a Python script exits 0 or with a Python exception (1), not an abort (134) or a signal.
# Each runs in its own temporary folder (a copy of its reproducer's folder); the project root
# is its working directory's parent for the scenes' relative `experiments/...` paths, so the
# Python scripts run from a copy of the project's `experiments/` beside them.
#
#   bash tools/dev/check_reproducers.sh REPRODUCERS_DIR [BUILD_DIR] [LIMIT]
#
# Prints one line per run (verdict, exit code, seconds, the last line of stderr) and exits 1 if
# any run broke a rule. py_save_device needs root (it makes a device node) and is skipped
# otherwise.
set -uo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
repro=$(cd "${1:?reproducers folder}" && pwd)
build=$(cd "${2:-$root/build/release}" && pwd)
limit=${3:-10}
vibro="$build/tools/vibro/vibro"
[ -x "$vibro" ] || { echo "error: $vibro is missing: build first" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failures=0

# run NAME DIR CMD...: runs CMD in DIR with the time limit; sets rc, secs, killed.
run() {
  local dir=$2
  shift 2
  local start end
  start=$(date +%s.%N)
  (cd "$dir" && exec "$@") > "$dir/stdout.txt" 2> "$dir/stderr.txt" &
  local pid=$!
  killed=""
  local waited=0
  while kill -0 "$pid" 2> /dev/null && [ "$waited" -lt $((limit * 10)) ]; do
    sleep 0.1
    waited=$((waited + 1))
  done
  if kill -0 "$pid" 2> /dev/null; then
    kill -TERM "$pid"
    killed=$(date +%s.%N)
    for _ in $(seq 1 20); do kill -0 "$pid" 2> /dev/null || break; sleep 0.1; done
    kill -0 "$pid" 2> /dev/null && { kill -KILL "$pid"; killed="ignored"; }
  fi
  wait "$pid"
  rc=$?
  end=$(date +%s.%N)
  secs=$(echo "$end - $start" | bc)
}

report() {  # VERDICT NAME DIR
  printf '%-4s %-44s rc=%-3s %6.2f s | %s\n' "$1" "$2" "$rc" "$secs" "$(tail -n 1 "$3/stderr.txt" 2> /dev/null | cut -c1-150)"
  [ "$1" = ok ] || failures=$((failures + 1))
}

for d in "$repro"/*/; do
  name=$(basename "$d")
  for scene in "$d"*.yaml; do
    [ -e "$scene" ] || continue
    w="$work/$name-$(basename "$scene" .yaml)"
    mkdir -p "$w/run"
    cp -r "$d". "$w/run/"
    ln -s "$root/experiments" "$w/experiments"
    run "$name/$(basename "$scene")" "$w/run" "$vibro" run "$(basename "$scene")" -o out.h5
    verdict=ok
    if [ "$killed" = ignored ] || { [ "$rc" -gt 128 ] && [ -z "$killed" ]; } || [ "$rc" -eq 5 ]; then
      verdict=FAIL
    elif [ -n "$killed" ]; then
      # A long run: said so before the limit, stopped at SIGTERM with 130 and nothing written.
      [ "$rc" -eq 130 ] && [ ! -e "$w/run/out.h5" ] && head -n -1 "$w/run/stderr.txt" | grep -qE "^warning:|progress" ||
        verdict=FAIL
    elif [ "$rc" -eq 0 ]; then
      [ -e "$w/run/out.h5" ] || verdict=FAIL
    else
      grep -q "^error:" "$w/run/stderr.txt" && [ ! -e "$w/run/out.h5" ] || verdict=FAIL
    fi
    report "$verdict" "$name/$(basename "$scene")" "$w/run"
  done
  for script in "$d"*.py; do
    [ -e "$script" ] || continue
    if [ "$name" = py_save_device ] && [ "$(id -u)" -ne 0 ]; then
      echo "skip $name/$(basename "$script") (needs root)"
      continue
    fi
    w="$work/$name-$(basename "$script" .py)"
    mkdir -p "$w"
    cp -r "$d". "$w/"
    ln -s "$root/experiments" "$w/experiments"
    run "$name/$(basename "$script")" "$w" env PYTHONPATH="$build/python" /usr/bin/python3 "$(basename "$script")"
    verdict=ok
    { [ -n "$killed" ] || [ "$rc" -gt 1 ]; } && verdict=FAIL
    # Result.save over a device node refuses (a Python exception), never replaces it.
    if [ "$name" = py_save_device ] && [ ! -c "$w/fullnode" ]; then verdict=FAIL; fi
    report "$verdict" "$name/$(basename "$script")" "$w"
  done
done
echo "$failures failed"
[ "$failures" -eq 0 ]

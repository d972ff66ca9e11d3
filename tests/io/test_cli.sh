#!/usr/bin/env bash
# The `vibro` command as a careless or hostile user drives it: every failure is one "error:" line
# and an exit code (tools/vibro/main.cpp), never an abort (134), a crash (139) or a hang, and
# leaves no file behind. One CTest test per case (tests/CMakeLists.txt); each case works in its
# own temporary directory, removed at the end.
#
#   tests/io/test_cli.sh CASE VIBRO SCENE     # SCENE: experiments/wagg2004/fig2_sticking_orbit.yaml
set -u
case_name=$1
vibro=$(realpath "$2")
fig2=$(realpath "$3")
work=$(mktemp -d "${TMPDIR:-/tmp}/vibro-cli-XXXXXX")
trap 'rm -rf "$work"' EXIT
cd "$work" || exit 1
failures=0

fail() { echo "FAILED: $*"; failures=$((failures + 1)); }

# expect CODE PATTERN COMMAND...: the exit code and a fragment of stderr (fixed string).
expect() {
  local code=$1 pattern=$2
  shift 2
  "$@" > out.txt 2> err.txt
  local got=$?
  [ "$got" -eq "$code" ] || fail "$*: exit code $got, expected $code; stderr: $(cat err.txt)"
  [ -z "$pattern" ] || grep -qF -- "$pattern" err.txt || fail "$*: stderr lacks '$pattern': $(cat err.txt)"
  [ "$(grep -c '^error:' err.txt)" -le 1 ] || fail "$*: more than one error line: $(cat err.txt)"
}

# files_are NAMES...: the working directory holds exactly these (sorted).
files_are() {
  local want got
  want=$(printf '%s\n' "$@" | sort | tr '\n' ' ')
  got=$(ls -A | grep -v -e '^out.txt$' -e '^err.txt$' | sort | tr '\n' ' ')
  [ "$got" = "$want" ] || fail "files: '$got', expected '$want'"
}

# stop PID SIGNAL: sends the signal and waits at most 60 s for the process to end (a regression
# fails instead of hanging the suite); sets `code` to its exit code.
stop() {
  kill -"$2" "$1"
  for _ in $(seq 600); do kill -0 "$1" 2> /dev/null || break; sleep 0.1; done
  if kill -0 "$1" 2> /dev/null; then
    fail "SIG$2 not honoured within 60 s"
    kill -KILL "$1"
  fi
  wait "$1"
  code=$?
}

small_sweep() {  # a sweep of the paper's system; $1: extra record keys, $2: sweep count
  cat <<EOF
model: {chain: {masses: [1, 1], springs: [1], dampers: [0.1], left_wall: {spring: 1, damper: 0.1}}}
forcing: {frequency: 0.255, cosine: [0.5, 0]}
stops:
  - {mass: 0, side: lower, position: -0.3, restitution: 0.7}
  - {mass: 1, side: upper, position: 0.1, restitution: 0.7}
record: {events: true$1}
run:
  kind: sweep
  transient_periods: 1
  periods: 5
  sweep: {parameters: [{path: forcing.frequency, linspace: [0.25, 0.27, $2]}]}
EOF
}

case "$case_name" in
  set_index_overflow)  # was: uncaught std::out_of_range from stoul, exit 134
    expect 2 "error: --set:1:1: forcing.cosine[99999999999999999999]: malformed path: index '99999999999999999999' is too large" \
      "$vibro" check "$fig2" --set 'forcing.cosine[99999999999999999999]=1'
    expect 2 "error: --set:2:19: forcing.frequency: expected a finite number, found 'fast'" \
      "$vibro" check "$fig2" --set forcing.frequency=0.26 --set forcing.frequency=fast
    expect 0 "" "$vibro" check "$fig2" --set 'forcing.cosine[1]=1e-308'
    small_sweep "" 3 | sed 's/path: forcing.frequency/path: "forcing.cosine[99999999999999999999]"/' > sweep.yaml
    expect 2 "sweep.yaml:11:" "$vibro" check sweep.yaml
    grep -qF "is too large" err.txt || fail "sweep path overflow: $(cat err.txt)"
    ;;
  not_a_file)  # was: /dev/zero read for ever into memory, a FIFO blocked for ever
    expect 2 "error: /dev/zero: is a character device: a scene must be a regular file" "$vibro" check /dev/zero
    mkfifo fifo
    expect 2 "error: fifo: is a FIFO (named pipe): a scene must be a regular file" timeout 60 "$vibro" check fifo
    mkdir folder
    expect 2 "error: folder: is a directory: a scene must be a regular file" "$vibro" run folder -o x.h5
    expect 2 "error: missing.yaml: cannot open the scene file: No such file or directory" "$vibro" info missing.yaml
    files_are fifo folder
    ;;
  threads)  # was: --threads 100000 segfaulted; -1 and a 20-digit count gave the parser's raw text, exits 105, 104
    small_sweep "" 3 > sweep.yaml
    expect 4 "--threads 100000: at most 1024 threads" "$vibro" run sweep.yaml -o s.h5 --threads 100000
    expect 4 "--threads 99999999999999999999: at most 1024 threads" "$vibro" run sweep.yaml -o s.h5 --threads 99999999999999999999
    expect 2 "error: --threads -1: expected a whole number of threads ≥ 0" "$vibro" run sweep.yaml -o s.h5 --threads -1
    expect 2 "error: --threads 1.5: expected a whole number" "$vibro" run sweep.yaml -o s.h5 --threads 1.5
    files_are sweep.yaml
    ;;
  arguments)  # was: CLI11's raw text over several lines, exit codes 106 (no scene), 109 (unknown option)
    for args in "run" "run --frobnicate x.yaml" "check" "info a.yaml b.yaml" "" "nonsense x.yaml" "run x.yaml --threads"; do
      # shellcheck disable=SC2086 (the words of each case are its arguments)
      expect 2 "(vibro --help lists the arguments)" "$vibro" $args
      [ "$(wc -l < err.txt)" -eq 1 ] || fail "vibro $args: not one line: $(cat err.txt)"
      grep -q '^error: ' err.txt || fail "vibro $args: no error: line: $(cat err.txt)"
    done
    expect 0 "" "$vibro" --help
    grep -qF "Exit codes: 0 success" out.txt || fail "--help does not list the exit codes: $(cat out.txt)"
    expect 0 "" "$vibro" run --help
    ;;
  sample_times_in_sweep)  # was: a sample time past one sweep value's span: terminate in a worker thread, exit 134
    small_sweep ", samples: {times: [0.5, 120]}" 3 > sweep.yaml  # span 5 × 2π/Ω: 125.7 at Ω = 0.25, 116.4 at 0.27
    expect 2 "record.samples.times[1]" "$vibro" run sweep.yaml -o s.h5 --threads 2
    grep -qF "forcing.frequency = 0.27" err.txt && grep -qF "makes the scene invalid" err.txt || fail "sample times: $(cat err.txt)"
    files_are sweep.yaml
    ;;
  memory)  # was: bad_alloc (exit 134) from a 100 000-mass chain with a wall, and from 1e6 × 1e9 samples
    /usr/bin/python3 -c "
n = 100000
print('model: {chain: {masses: [%s], springs: [%s], left_wall: {spring: 1}}}' % (', '.join(['1'] * n), ', '.join(['1'] * (n - 1))))
print('forcing: {frequency: 0.8, cosine: [1%s]}' % (', 0' * (n - 1)))
print('stops: [{mass: 0, side: upper, position: 0.5, restitution: 0.5}]')" > chain.yaml
    # 8 GB of address space: the modal set-up of 10^5 masses (≈ 25 bytes × n² = 250 GB) cannot fit
    # on any machine this runs on, whatever its memory. (Not under AddressSanitizer, which
    # reserves terabytes of address space for its shadow memory: there the machine's memory decides.)
    limit=8000000
    [ -z "${ASAN_OPTIONS:-}" ] || limit=unlimited
    # Refused where the masses are read (exit 2, as a scene too large to parse), before the chain is built.
    (ulimit -v $limit; expect 2 "chain.yaml:1:25: model.chain.masses: a chain of 100000 masses (every engine holds n × n modes or matrices) needs about 250 GB" \
      "$vibro" check chain.yaml; exit $failures) || failures=$((failures + 1))
    (ulimit -v $limit; expect 2 "needs about" "$vibro" run chain.yaml -o c.h5; exit $failures) || failures=$((failures + 1))
    small_sweep ", samples: {per_period: 1000000}" 3 | sed 's/periods: 5/periods: 1e9/' > huge.yaml
    expect 4 "the recording (1e+15 samples" "$vibro" run huge.yaml -o h.h5
    files_are chain.yaml huge.yaml
    ;;
  output_rules)  # was: outputs and the scene itself overwritten silently; a symlinked .partial written through
    cp "$fig2" scene.yaml
    expect 0 "Results in out.h5" "$vibro" run scene.yaml -o out.h5
    cp out.h5 first.h5
    expect 3 "error: out.h5: exists: not overwritten (use --force to replace it)" "$vibro" run scene.yaml -o out.h5
    cmp -s out.h5 first.h5 || fail "out.h5 changed without --force"
    expect 0 "Results in out.h5" "$vibro" run scene.yaml -o out.h5 --force
    expect 3 "error: scene.yaml: is the scene file being run" "$vibro" run scene.yaml -o scene.yaml --force
    cmp -s scene.yaml "$fig2" || fail "the scene was modified"
    mkdir d
    expect 3 "error: d: is a directory" "$vibro" run scene.yaml -o d
    echo precious > victim
    ln -s victim x.h5.partial
    expect 3 "x.h5.partial: left by a run that was killed: delete it, or add --force" "$vibro" run scene.yaml -o x.h5
    [ "$(cat victim)" = precious ] || fail "written through the symbolic link"
    files_are d first.h5 out.h5 scene.yaml victim x.h5.partial
    ;;
  concurrent)  # was: the second writer truncated the first's .partial; the first renamed garbage, exit 0
    cat > slow.yaml <<EOF
model: {chain: {masses: [1], left_wall: {spring: 1, damper: 0.1}}}
forcing: {frequency: 1, cosine: [1]}
stops: [{mass: 0, side: upper, position: 0.5, restitution: 0.5}]
run: {periods: 1e8}
EOF
    "$vibro" run slow.yaml -o w.h5 2> first.txt &
    first=$!
    for _ in $(seq 600); do [ -e w.h5.lock ] && break; sleep 0.1; done
    expect 3 "error: w.h5: another run is writing it (process $first holds w.h5.lock)" "$vibro" run slow.yaml -o w.h5 --force
    stop $first TERM
    [ $code -eq 130 ] || fail "the interrupted simulation exited with $code: $(cat first.txt)"
    grep -qF "w.h5 was not written" first.txt || fail "interrupted simulation: $(cat first.txt)"
    rm first.txt
    files_are slow.yaml
    ;;
  signal_in_point)  # was: SIGTERM ignored until the point under way ended (772 s)
    small_sweep "" 2 | sed 's/periods: 5/periods: 1e8/' > long.yaml
    "$vibro" run long.yaml -o l.h5 --threads 1 2> run.txt &
    pid=$!
    for _ in $(seq 600); do [ -e l.h5.partial ] && break; sleep 0.1; done
    sleep 1
    stop $pid TERM  # a point of 1e8 periods takes hours: only the event loop's polling ends it
    [ $code -eq 130 ] || fail "exit code $code after SIGTERM: $(cat run.txt)"
    grep -qF "Interrupted: 0 of 2 sweep points are kept in l.h5.partial" run.txt || fail "$(cat run.txt)"
    rm run.txt
    files_are l.h5.partial long.yaml
    ;;
  signal_hangup)  # a closed terminal: SIGHUP stops a sweep as SIGTERM does, the lock removed
    small_sweep "" 2 | sed 's/periods: 5/periods: 1e8/' > long.yaml
    "$vibro" run long.yaml -o l.h5 --threads 1 2> run.txt &
    pid=$!
    for _ in $(seq 600); do [ -e l.h5.partial ] && break; sleep 0.1; done
    sleep 1
    stop $pid HUP
    [ $code -eq 130 ] || fail "exit code $code after SIGHUP: $(cat run.txt)"
    grep -qF "Interrupted: 0 of 2 sweep points are kept in l.h5.partial" run.txt || fail "$(cat run.txt)"
    rm run.txt
    files_are l.h5.partial long.yaml
    ;;
  signal_in_segment)  # was: "Interrupted at t = 0" after seconds of search in one long segment
    # Unforced, at rest between two stops: one segment over the whole run, searched step by step.
    cat > rest.yaml <<EOF
model: {chain: {masses: [3], left_wall: {spring: 1.4, damper: 0.14}}}
forcing: {frequency: 1e-9, cosine: [0]}
stops: [{mass: 0, side: lower, position: -0.2, restitution: 0.9}, {mass: 0, side: upper, position: 0.1, restitution: 0}]
run: {periods: 2}
EOF
    "$vibro" run rest.yaml -o r.h5 2> run.txt &
    pid=$!
    sleep 2
    stop $pid TERM
    [ $code -eq 130 ] || fail "exit code $code after SIGTERM: $(cat run.txt)"
    grep -qE "Interrupted at t = [1-9][0-9.e+]* \(the state kept is the one at t = 0, where the segment began\): r.h5 was not written" run.txt ||
      fail "$(cat run.txt)"
    rm run.txt
    files_are rest.yaml
    ;;
  signal_in_continue)  # was: locate and continue ignored SIGTERM's flag, leaving a .partial behind
    # Steps of 1e-7 over the whole range: hours of continuation, ended only by the signal.
    sed -e '/^    max_points: /d' -e 's/^    max_step: .*/    max_step: 1e-7\n    max_points: 1000000/' -e 's/^    step: .*/    step: 1e-7/' \
      "$(dirname "$fig2")/continuation.yaml" > cont.yaml
    "$vibro" run cont.yaml -o c.h5 2> run.txt > /dev/null &
    pid=$!
    for _ in $(seq 600); do [ -e c.h5.partial ] && break; sleep 0.1; done
    sleep 1
    stop $pid TERM
    [ $code -eq 130 ] || fail "exit code $code after SIGTERM: $(tail -3 run.txt)"
    rm run.txt
    files_are c.h5 cont.yaml  # the file, written with what was done, status interrupted
    ;;
  signal_taylor)  # the Taylor engine (nonlinear forces) polls the same flag: SIGTERM ends a diagram's point
    cat > duffing.yaml <<EOF
model: {chain: {masses: [1], left_wall: {spring: 1, damper: 0.05}}}
forcing: {frequency: 0.85, cosine: [0.8]}
stops: [{mass: 0, side: upper, position: 0.6, restitution: 0.8}]
parameters: {beta: 0.5}
forces: [{cubic_spring: {mass: 0, coefficient: beta}}]
run:
  kind: diagram
  transient_periods: 1e8
  diagram: {path: forcing.frequency, linspace: [0.85, 0.9, 3], points: 8, max_period: 4}
EOF
    "$vibro" run duffing.yaml -o d.h5 --threads 1 2> run.txt &
    pid=$!
    for _ in $(seq 600); do [ -e d.h5.partial ] && break; sleep 0.1; done
    sleep 1
    stop $pid TERM  # a transient of 1e8 periods takes hours: only the event loop's polling ends it
    [ $code -eq 130 ] || fail "exit code $code after SIGTERM: $(tail -3 run.txt)"
    rm run.txt
    files_are d.h5 duffing.yaml  # the file, written with what was done, status interrupted
    ;;
  full_disk)  # was: the sweep printed the error, then segfaulted in HDF5's exit handler (139)
    small_sweep ", samples: {per_period: 2000}" 8 > sweep.yaml
    cp "$fig2" scene.yaml
    (
      trap '' XFSZ  # a write past the limit fails with EFBIG instead of killing the process
      ulimit -f 200
      expect 3 "File too large" "$vibro" run sweep.yaml -o s.h5 --threads 1
      expect 3 "File too large" "$vibro" run scene.yaml -o f.h5 --set record.samples.per_period=20000
      exit $failures
    ) || failures=$((failures + 1))
    files_are s.h5.partial scene.yaml sweep.yaml  # the sweep keeps its partial for --resume
    ;;
  prompt_exit)  # was: "completed" printed after 0.5 s, and the process lived on for 12 s
    cat > s.yaml <<EOF
model: {chain: {masses: [0.388223, 2.988727, 2.915514], springs: [0.859055, 0.431005], dampers: [0.190722, 0.258244]}}
forcing: {frequency: 0.10563}
stops: []
record: {events: true, samples: {times: [0.0377, 2.2935]}}
run: {kind: simulate, transient_periods: 1, periods: 3}
EOF
    start=$(date +%s%N)
    expect 0 "completed" timeout 30 "$vibro" run s.yaml -o o.h5
    elapsed=$(( ($(date +%s%N) - start) / 1000000 ))
    [ "$elapsed" -lt 5000 ] || fail "the process ended $elapsed ms after it started (the run itself takes 0.01 s)"
    files_are o.h5 s.yaml
    ;;
  warn_slow)  # was: minutes at ~0 % progress with no word (a damper of 1e10 on a 6-mass chain)
    cat > s.yaml <<EOF
model: {chain: {masses: [2, 1.6, 1.9, 1.7, 1.8, 2.3], springs: [0.19, 2.8, 0.65, 0.31, 0.71], dampers: [0.27, 0.08, 1e10, 0.29, 0.21], left_wall: {spring: 2.9, damper: 0.1}}}
forcing: {frequency: 1.91616, cosine: [0, 0, 0, -0.09, 0.66, 0.8]}
stops: [{mass: 5, side: lower, position: -0.0, restitution: 0.83}]
run: {kind: simulate, transient_periods: 10, periods: 1}
EOF
    "$vibro" run s.yaml -o o.h5 > out.txt 2> run.txt &
    pid=$!
    sleep 2
    stop $pid TERM
    [ $code -eq 130 ] || fail "exit code $code after SIGTERM: $(tail -3 run.txt)"
    grep -qE "^warning: this run needs about [0-9.e+]+ steps of the certified event search .*progress lines follow" run.txt ||
      fail "no estimate of the work: $(head -3 run.txt)"
    grep -qE "^Interrupted during the transient at t = " run.txt || fail "interruption line: $(tail -1 run.txt)"
    rm run.txt
    files_are s.yaml
    ;;
  *)
    echo "unknown case $case_name"
    exit 2
    ;;
esac
if [ $failures -ne 0 ]; then
  echo "$case_name: $failures failure(s)"
  exit 1
fi
echo "$case_name: passed"

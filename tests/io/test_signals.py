#!/usr/bin/env python3
"""SIGTERM answered within a second by `vibro run`, in every run kind and in its slow phases.

Each case writes a scene chosen to sit in one phase for several seconds (a dense chain's check,
a large contact set's flow, the modal engine's set-up and run, the layout of 3e7 sample times,
the evaluation of thousands of samples in one segment free of events, one long event-search
segment, in the recorded periods and in the transient, a sweep point,
Newton-Krylov shooting on a 1000-mass chain, shooting on a dense chain (the section probe's scan,
tangent maps), a continuation's start on it and its corrector, the modal family engine a
continuation makes at a parameter value, the modal engine's full-Jacobian tangent map of a
continuation's start, a two-parameter curve, locate, basin, diagram and Lyapunov points and a
later point's engine set-up on a long modal chain, the Taylor engine), starts `vibro run` on it in a folder of
its own, waits until the run is in that phase (its output's lock made, or a fixed time for the
check, which makes no file), sends SIGTERM and measures how long the process takes to end.

It asserts: the process ends within LIMIT seconds of the signal; exit code 130; the last line on
stderr is the kind's interruption line; the files left are the documented ones (a simulation and
a run stopped before it started leave nothing, a sweep keeps OUT.partial, the other kinds write
OUT with what was done, status interrupted); never a .lock.

LIMIT is 1 s (the guarantee: docs/results.md, "Signals") plus 1 s for a loaded 2-core machine:
the cases run four at a time beside the rest of the suite (`ctest -j2`), so a process that has
seen the signal may wait a scheduler's time slice or two before it runs, and it still has to
close and rename its HDF5 file. The times measured are printed (on an idle machine: 0.02-0.3 s).

    tests/io/test_signals.py --vibro build/release/tools/vibro/vibro --experiments experiments [CASE ...]
"""
import argparse
import concurrent.futures
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

LIMIT = 2.0  # seconds from the signal to the process's end: 1 s guaranteed + 1 s for a loaded machine


def numbers(values):
    return "[" + ", ".join(values) + "]"


def chain(n, engine, run, damper="0.02"):
    """A chain of n unit masses and springs (dampers proportional to the springs), driven at
    mass 0, a stop on every tenth of it (the first with r = 0, so that it sticks)."""
    lines = [
        "model: {chain: {masses: %s, springs: %s, dampers: %s, left_wall: {spring: 1, damper: %s}}}"
        % (numbers(["1"] * n), numbers(["1"] * (n - 1)), numbers([damper] * (n - 1)), damper),
        "forcing: {frequency: 0.8, cosine: %s}" % numbers(["0.6"] + ["0"] * (n - 1)),
        "stops:",
    ]
    for j in range(0, n, max(1, n // 10)):
        lines.append("  - {mass: %d, side: upper, position: 0.1, restitution: %s}" % (j, "0" if j == 0 else "0.5"))
    lines.append("solver: {engine: %s}" % engine)
    lines.append(run)
    return "\n".join(lines) + "\n"


SMALL_SWEEP = """model: {chain: {masses: [1, 1], springs: [1], dampers: [0.1], left_wall: {spring: 1, damper: 0.1}}}
forcing: {frequency: 0.255, cosine: [0.5, 0]}
stops:
  - {mass: 0, side: lower, position: -0.3, restitution: 0.7}
  - {mass: 1, side: upper, position: 0.1, restitution: 0.7}
record: {events: true}
run:
  kind: sweep
  transient_periods: 1
  periods: 1e8
  sweep: {parameters: [{path: forcing.frequency, linspace: [0.25, 0.27, 2]}]}
"""

# One mass hitting a stop every period, 3·10⁷ sample times: laying them out takes a second or more.
MANY_SAMPLES = """model: {chain: {masses: [1], left_wall: {spring: 1, damper: 0.01}}}
forcing: {frequency: 1, cosine: [1]}
stops: [{mass: 0, side: upper, position: 0.5, restitution: 0.9}]
record: {samples: {per_period: 1000000}}
run: {periods: 30}
"""

DENSE_ORBIT = "run: {kind: orbit, transient_periods: 0, orbit: {period: 1}}"

# One period of a 1000-mass modal chain whose stop is never reached: one segment free of events,
# its 5000 sample times evaluated at O(n²) each (seconds; polled between batches).
SAMPLES_IN_ONE_SEGMENT = chain(1000, "modal", "record: {samples: {per_period: 5000}}\nrun: {periods: 1}").replace(
    "position: 0.1", "position: 100")

MODAL_CONTINUE = "run: {kind: continue, transient_periods: 0, continue: {path: forcing.frequency, range: [0.7, 0.9], step: 0.01%s}}"

# The point-by-point kinds on a long modal chain whose stops are never reached (each point's orbit
# is quick): every point makes its own engine, the chain's modes (seconds, run where the wait is
# bounded), and the signal comes 0.3 s into a later point's set-up, after a point is done.
SET_UP_MASSES = 3000
GRID = "path: forcing.frequency, linspace: [0.7, 0.8, 3]"


def free_chain(run):
    return chain(SET_UP_MASSES, "modal", run).replace("position: 0.1", "position: 100")

LONG_SEGMENT = """model: {chain: {masses: [3], left_wall: {spring: 1.4, damper: 0.14}}}
forcing: {frequency: 1e-9, cosine: [0]}
stops: [{mass: 0, side: lower, position: -0.2, restitution: 0.9}, {mass: 0, side: upper, position: 0.1, restitution: 0}]
run: {periods: 2}
"""


def experiment(args, path, *replace):
    """An experiment's scene, with (pattern, replacement) line edits."""
    with open(os.path.join(args.experiments, path)) as f:
        text = f.read()
    for pattern, replacement in replace:
        text, count = re.subn(pattern, replacement, text, flags=re.M)
        assert count > 0, f"{path}: no line matches {pattern}"
    return text


SIMULATION_NOT_WRITTEN = r"^Interrupted at t = .*: o\.h5 was not written \(a simulation keeps nothing"
WRITTEN = r"Results in o\.h5\.$"


def cases(args):
    """name: (scene text, extra arguments, when to signal, last stderr line, files left[, a
    pattern stderr must hold: what was done])."""
    n = 200
    ONE_STOP_200 = "\n".join([
        "model: {chain: {masses: %s, springs: %s, dampers: %s, left_wall: {spring: 1, damper: 0.02}}}"
        % (numbers(["1"] * n), numbers(["1"] * (n - 1)), numbers(["0.02"] * (n - 1))),
        "forcing: {frequency: 0.8, cosine: %s}" % numbers(["0.6"] + ["0"] * (n - 1)),
        "stops: [{mass: 0, side: upper, position: 0.1, restitution: 0.5}]",
        "solver: {engine: dense}", "{run}", ""]).replace("{", "{{").replace("}", "}}").replace("{{run}}", "{run}")
    return {
        # The check before anything is written: the dense 1500-mass chain's n × n matrices are
        # tested for symmetry and definiteness by Eigen decompositions (seconds, not pollable).
        "check: dense set-up of a 1500-mass chain": (
            chain(1500, "dense", "run: {periods: 3}"), [], 1.5,
            r"^Interrupted before the run started: o\.h5 was not written\.$", []),
        # A contact set's flow on the dense engine: eigenvectors, Schur form and exponential of a
        # 500 × 500 generator (seconds; run where the wait is bounded).
        "simulate: dense contact-set flow of a 250-mass chain": (
            chain(250, "dense", "run: {periods: 3}"), [], "lock+0.5", SIMULATION_NOT_WRITTEN, []),
        # The modal engine's set-up: the modes of a 3000-mass chain, one LAPACK call (seconds; run
        # where the wait is bounded).
        "simulate: modal engine's set-up of a 3000-mass chain": (
            chain(3000, "modal", "run: {periods: 3}"), [], "lock+0.5", SIMULATION_NOT_WRITTEN, []),
        # Laying out 3·10⁷ sample times (polled while it lays them out).
        "simulate: laying out 3e7 sample times": (
            MANY_SAMPLES, [], "lock+0.2", SIMULATION_NOT_WRITTEN, []),
        "simulate: modal engine, 1000-mass chain": (
            chain(1000, "modal", "run: {periods: 1e6}"), [], "lock+1", SIMULATION_NOT_WRITTEN, []),
        # Evaluating the samples of one segment free of events (polled every few milliseconds).
        "simulate: 5000 samples in one segment of a 1000-mass modal chain": (
            SAMPLES_IN_ONE_SEGMENT, [], "lock+2", SIMULATION_NOT_WRITTEN, []),
        "simulate: event search in one long segment": (
            LONG_SEGMENT, [], "lock+1", SIMULATION_NOT_WRITTEN, []),
        # The same in the transient: the line says so ("Interrupted during the transient at t = …").
        "simulate: event search in the transient": (
            LONG_SEGMENT.replace("run: {periods: 2}", "run: {transient_periods: 1, periods: 2}"), [], "lock+1",
            r"^Interrupted during the transient at t = .*: o\.h5 was not written \(a simulation keeps nothing", []),
        "simulate: Taylor engine (forces)": (
            experiment(args, "examples/duffing_impact.yaml", (r"^(\s*)periods: .*$", r"\1periods: 1e5"),
                       (r"per_period: 100", "per_period: 1")),
            [], "lock+1", SIMULATION_NOT_WRITTEN, []),
        "sweep: inside a point": (
            SMALL_SWEEP, ["--threads", "1"], "lock+1",
            r"^Interrupted: 0 of 2 sweep points are kept in o\.h5\.partial", ["o.h5.partial"]),
        "orbit: Newton-Krylov shooting on a 1000-mass chain": (
            experiment(args, "chains/chain_1000_orbit.yaml"), [], "lock+1", WRITTEN, ["o.h5"]),
        # Shooting on the dense engine: on 150 masses with 15 stops the guess's section probe
        # scans every segment for the gaps' peaks (seconds each, polled); on 200 masses with one
        # stop each Newton iteration builds the flows of its tangent map and carries J through
        # them (O(n³) products, bounded: bounded_wait.hpp), then factorises J − I.
        "orbit: dense 150-mass chain, the section probe": (
            chain(150, "dense", DENSE_ORBIT), [], "lock+2", WRITTEN, ["o.h5"]),
        "orbit: dense 200-mass chain, tangent maps": (
            ONE_STOP_200.format(run=DENSE_ORBIT), [], "lock+10", WRITTEN, ["o.h5"]),
        # Continuation from that orbit: the start's shooting, interrupted, writes the file.
        "continue: dense 200-mass chain, the start's shooting": (
            ONE_STOP_200.format(run="run: {kind: continue, transient_periods: 0, continue: "
                                    "{path: forcing.frequency, range: [0.7, 0.9], step: 0.01}}"),
            [], "lock+10", WRITTEN, ["o.h5"]),
        # Continuation on the modal engine makes its own engine at each parameter value: the
        # modes of the 3000-mass chain again (run where the wait is bounded). The run's engine
        # for the transient makes them first, so the signal comes 0.3 s into the second set-up
        # on a thread of its own (seconds long).
        "continue: the modal family engine's set-up, 3000-mass chain": (
            chain(3000, "modal", MODAL_CONTINUE % ""), [], "bounded#2+0.3", WRITTEN, ["o.h5"]),
        # The start's shooting on the modal engine forms the full Jacobian of each map: 2N = 1200
        # directions through every event of the period, O(N³) at each held set (about 7 s for
        # this map; polled between blocks of columns and between events). The set-ups before it
        # take a few hundredths of a second.
        "continue: the modal engine's full-Jacobian tangent map, 600-mass chain": (
            chain(600, "modal", MODAL_CONTINUE % ""), [], "lock+1", WRITTEN, ["o.h5"]),
        "continue: the corrector, steps of 1e-7": (
            experiment(args, "wagg2004/continuation.yaml", (r"^(\s*)max_step: .*$", r"\1max_step: 1e-7"),
                       (r"^(\s*)max_points: .*$", r"\1max_points: 1000000"), (r"^(\s*)step: .*$", r"\1step: 1e-7")),
            [], "lock+1", WRITTEN, ["o.h5"]),
        "continue: two-parameter curves": (
            experiment(args, "examples/impact_oscillator_curves.yaml", (r"^(\s*)step: 0\.02(\s*)$", r"\1step: 0.0005\2"),
                       (r"^(\s*)max_points: 60", r"\1max_points: 100000")),
            [], "lock+1", WRITTEN, ["o.h5"]),
        "locate: orbits over a grid": (
            experiment(args, "wagg2004/rising_scan.yaml", (r"linspace: \[0\.24, 0\.28, 161\]", "linspace: [0.24, 0.28, 100001]")),
            [], "lock+1", WRITTEN, ["o.h5"]),
        "basin: grid points": (
            experiment(args, "chaos/basin_wagg.yaml"), ["--threads", "2"], "lock+1", WRITTEN, ["o.h5"]),
        "diagram: points": (
            experiment(args, "chaos/bifurcation_wagg.yaml"), [], "lock+1", WRITTEN, ["o.h5"]),
        "lyapunov: points": (
            experiment(args, "chaos/lyapunov_chain.yaml"), [], "lock+1", WRITTEN, ["o.h5"]),
        # A later point's engine set-up (the first point's is bounded set-up 1; a basin's run that
        # fixes its scales comes before it): the points done are written, status interrupted.
        "locate: a later point's engine set-up": (
            free_chain("run: {kind: locate, transient_periods: 0, locate: {%s, max_period: 1, max_periods: 2}}" % GRID),
            ["--threads", "1"], "bounded#2+0.3", WRITTEN, ["o.h5"], r"\(1 grid points, 1 orbits"),
        "basin: a later point's engine set-up": (
            free_chain("run: {kind: basin, transient_periods: 0, basin: {parameters: [{%s}, {path: 'forcing.cosine[0]', "
                       "values: [0.6]}], max_period: 1, max_periods: 2, seed_stride: 1}}" % GRID),
            ["--threads", "1"], "bounded#3+0.3", WRITTEN, ["o.h5"], r"^  2 points not run: interrupted \(label -3\)$"),
        "diagram: a later value's engine set-up": (
            free_chain("run: {kind: diagram, transient_periods: 0, diagram: {%s, points: 2, directions: up, "
                       "max_period: 1, settle: 0}}" % GRID),
            ["--threads", "1"], "bounded#2+0.3", WRITTEN, ["o.h5"], r", 2 not reached \(up: at forcing\.frequency = 0\.75: interrupted while its engine was set up\)"),
        "lyapunov: a later point's engine set-up": (
            free_chain("run: {kind: lyapunov, transient_periods: 0, lyapunov: {%s, count: 1, transient: 0, align: 0, "
                       "periods: 1}}" % GRID),
            ["--threads", "1"], "bounded#2+0.3", WRITTEN, ["o.h5"],
            r" 2 points not reached \(at forcing\.frequency = 0\.75: interrupted while its engine was set up\)\.$"),
    }


def threads(pid):
    """The process's thread count (0 once it has ended)."""
    try:
        with open(f"/proc/{pid}/status") as f:
            return next(int(line.split()[1]) for line in f if line.startswith("Threads:"))
    except (OSError, StopIteration):
        return 0


def run_case(args, name, spec):
    scene, extra, when, last_line, files, *said = spec
    work = tempfile.mkdtemp(prefix="vibro-signals-", dir=args.work)
    try:
        with open(os.path.join(work, "s.yaml"), "w") as f:
            f.write(scene)
        with open(os.path.join(work, "err.txt"), "w") as err:
            p = subprocess.Popen([args.vibro, "run", "s.yaml", "-o", "o.h5"] + extra, cwd=work,
                                 stdout=subprocess.DEVNULL, stderr=err)
        problems = []
        if isinstance(when, str) and when.startswith("lock+"):  # S seconds after the run made its output's lock
            deadline = time.monotonic() + 60
            while not os.path.exists(os.path.join(work, "o.h5.lock")) and p.poll() is None and time.monotonic() < deadline:
                time.sleep(0.02)
            time.sleep(float(when[5:]))
        elif isinstance(when, str):  # "bounded#K+S": S seconds into the run's K-th bounded set-up, the
            # K-th time it runs a computation on a thread of its own (bounded_wait.hpp: 2 threads)
            k, after = when[8:].split("+")
            seen, inside, deadline = 0, False, time.monotonic() + 120
            while seen < int(k) and p.poll() is None and time.monotonic() < deadline:
                count = threads(p.pid)
                if count >= 2 and not inside:
                    seen += 1
                inside = count >= 2
                time.sleep(0.005)
            time.sleep(float(after))
        else:
            time.sleep(when)
        if p.poll() is not None:
            return name, None, [f"ended before the signal (exit code {p.returncode}): the case no longer sits in its phase"]
        start = time.monotonic()
        p.send_signal(signal.SIGTERM)
        try:
            code = p.wait(60)
        except subprocess.TimeoutExpired:
            p.kill()
            code = p.wait()
            problems.append("SIGTERM not honoured within 60 s")
        seconds = time.monotonic() - start
        with open(os.path.join(work, "err.txt")) as f:
            lines = [line for line in f.read().splitlines() if line.strip()]
        last = lines[-1] if lines else ""
        if seconds > LIMIT:
            problems.append(f"ended {seconds:.2f} s after SIGTERM (limit {LIMIT} s)")
        if code != 130:
            problems.append(f"exit code {code}, expected 130")
        if not re.search(last_line, last):
            problems.append(f"last stderr line {last!r} does not match {last_line!r}")
        for pattern in said:
            if not any(re.search(pattern, line) for line in lines):
                problems.append(f"no stderr line matches {pattern!r}")
        left = sorted(f for f in os.listdir(work) if f not in ("s.yaml", "err.txt"))
        if left != sorted(files):
            problems.append(f"files left: {left}, expected {sorted(files)}")
        for f in files:
            if f == "o.h5" and os.path.exists(os.path.join(work, f)):
                with open(os.path.join(work, f), "rb") as h:
                    data = h.read()
                if not data.startswith(b"\x89HDF\r\n\x1a\n") or b"interrupted" not in data:
                    problems.append("o.h5 is not an HDF5 file with status interrupted")
        return name, seconds, problems
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--vibro", required=True)
    parser.add_argument("--experiments", required=True)
    parser.add_argument("--work", default=None, help="folder for the cases' temporary folders")
    parser.add_argument("--parallel", type=int, default=4)
    parser.add_argument("cases", nargs="*")
    args = parser.parse_args()
    args.vibro = os.path.abspath(args.vibro)
    if args.work:
        os.makedirs(args.work, exist_ok=True)
    table = cases(args)
    chosen = args.cases or list(table)
    failed = 0
    began = time.monotonic()
    with concurrent.futures.ThreadPoolExecutor(args.parallel) as pool:
        for name, seconds, problems in pool.map(lambda n: run_case(args, n, table[n]), chosen):
            took = "-" if seconds is None else f"{seconds:.2f} s"
            print(f"{'FAILED: ' if problems else 'ok      '}{name}: ended {took} after SIGTERM", flush=True)
            for p in problems:
                print(f"        {p}", flush=True)
            failed += bool(problems)
    print(f"{len(chosen) - failed} of {len(chosen)} cases passed in {time.monotonic() - began:.1f} s")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

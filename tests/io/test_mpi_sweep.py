#!/usr/bin/env python3
"""MPI sweeps: `mpirun -np 2 vibro run` must write the same data as one process, bit for bit.

    python3 tests/io/test_mpi_sweep.py CASE --vibro BUILD/tools/vibro/vibro \
        --driver BUILD/tests/mpi_sweep_driver --mpirun mpirun --work DIR

CASE is one of
  plain    a 1-D sweep recording everything (events, contacts, samples, Poincaré, statistics) on
           the paper's system, which sticks and chatters: 2 processes × 1 thread against one
           process on 2 threads;
  follow   a 1-D followed sweep (one chain: it runs on one process) and a 2-D followed sweep
           (rows split across the processes), each against one process;
  resume   sweeps stopped after a few points under MPI (exit 130, OUT.partial kept, OUT not
           made), then finished with `mpirun … vibro run --resume` — a plain sweep and a 2-D
           followed one cut in the middle of a row (rank 0 sends the row's state to the others);
           the result equals one uninterrupted process;
  basin    a run.kind: basin (Ω = 1.2, two coexisting orbits) on 2 processes × 1 thread against
           one process on 2 threads;
  errors   bad input and a stale OUT.partial under MPI: exit code 2, one message (from rank 0),
           no file, no hang;
  taylor   a scene with nonlinear forces (the Duffing impact oscillator, on the Taylor engine):
           a sweep recording everything and a basin, 2 processes × 1 thread against one process.

"Same" is exact: every dataset equal in shape, type and every bit (NaN-free by construction of
the files, so comparing the raw bytes decides), the same objects, and the same attributes,
except /meta's date, wall_time and threads (and resumed, after --resume), which describe the
run, not its results (threads must then be the sum over the processes). Runs as root in CI, where Open MPI
needs OMPI_ALLOW_RUN_AS_ROOT(_CONFIRM), and oversubscribes, for machines with fewer cores.
Exit status 0 if every check holds, 1 with one line per failure.
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile

import h5py
import numpy as np

FAILURES = []
RUN_ATTRIBUTES = {("/meta", "date"), ("/meta", "wall_time"), ("/meta", "threads")}
TIMEOUT = 240  # seconds for one command; each takes < 5 s on an idle 2-core machine

BASE = """\
# The paper's system (Wagg 2004, fig. 2), short runs that stick, chatter and impact.
name: mpi-test
model:
  chain: {masses: [1, 1], springs: [1], dampers: [0.1], left_wall: {spring: 1, damper: 0.1}}
forcing: {frequency: 0.255, cosine: [0.5, 0]}
stops:
  - {mass: 0, side: lower, position: -0.3, restitution: 0.7, name: s1}
  - {mass: 1, side: upper, position: 0.1, restitution: 0.7, name: s2}
record:
  events: true
  contacts: true
  statistics: true
  poincare: true
  samples: {per_period: 16}
run:
  kind: sweep
  transient_periods: 20
  periods: 3
  sweep:
"""
SWEEPS = {
    "plain": """\
    parameters:
      - {path: forcing.frequency, linspace: [0.24, 0.28, 9]}
""",
    "follow1": """\
    parameters:
      - {path: forcing.frequency, linspace: [0.25, 0.27, 6]}
    follow: true
""",
    "follow2": """\
    parameters:
      - {path: forcing.frequency, linspace: [0.25, 0.27, 4]}
      - {path: "stops[1].position", values: [0.08, 0.1, 0.12]}
    follow: true
""",
}

BASIN = """\
# The paper's system at Ω = 1.2: a period-2 and a period-1 orbit coexist (experiments/chaos/).
name: mpi-basin
model:
  chain: {masses: [1, 1], springs: [1], dampers: [0.1], left_wall: {spring: 1, damper: 0.1}}
forcing: {frequency: 1.2, cosine: [0.5, 0]}
stops:
  - {mass: 0, side: lower, position: -0.3, restitution: 0.7, name: s1}
  - {mass: 1, side: upper, position: 0.1, restitution: 0.7, name: s2}
initial: {x: [0, 0], v: [0, 0]}
run:
  kind: basin
  basin:
    parameters:
      - {path: "initial.x[0]", linspace: [-0.29, 0.6, 9]}
      - {path: "initial.v[0]", linspace: [-0.6, 0.6, 7]}
    seed_stride: 4
"""


def fail(message):
    FAILURES.append(message)


def mpi_env():
    env = dict(os.environ)
    env["OMPI_ALLOW_RUN_AS_ROOT"] = "1"
    env["OMPI_ALLOW_RUN_AS_ROOT_CONFIRM"] = "1"
    env["OMPI_MCA_rmaps_base_oversubscribe"] = "1"
    return env


def run(command, what):
    """Runs a command; returns (exit code, stderr)."""
    try:
        done = subprocess.run(command, env=mpi_env(), capture_output=True, text=True, timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        fail(f"{what}: no answer after {TIMEOUT} s (hang?): {' '.join(command)}")
        return None, ""
    return done.returncode, done.stderr


def expect(command, what, code):
    got, err = run(command, what)
    if got is not None and got != code:
        fail(f"{what}: exit code {got}, expected {code}: {' '.join(command)}\n{err}")
    return err


def compare(one, many, what, processes, threads_each, run_attributes=RUN_ATTRIBUTES):
    """Every object, dataset and attribute of `one` and `many` agree (see the docstring)."""
    if not (os.path.exists(one) and os.path.exists(many)):
        fail(f"{what}: missing file {one if not os.path.exists(one) else many}")
        return
    with h5py.File(one, "r") as a, h5py.File(many, "r") as b:
        names_a, names_b = [], []
        a.visit(names_a.append)
        b.visit(names_b.append)
        if names_a != names_b:
            fail(f"{what}: objects differ: {sorted(set(names_a) ^ set(names_b))}")
            return
        datasets = 0
        for name in ["/"] + names_a:
            x, y = a[name], b[name]
            if isinstance(x, h5py.Dataset):
                datasets += 1
                if x.dtype != y.dtype or x.shape != y.shape:
                    fail(f"{what}: /{name}: {x.dtype}{x.shape} against {y.dtype}{y.shape}")
                elif x.dtype.kind in "fiu":
                    if x.size and x[()].tobytes() != y[()].tobytes():
                        fail(f"{what}: /{name}: values differ")
                elif not np.array_equal(x[()], y[()]):
                    fail(f"{what}: /{name}: values differ")
            path = "/" + name.lstrip("/")
            if sorted(x.attrs.keys()) != sorted(y.attrs.keys()):
                fail(f"{what}: {path}: attributes {sorted(x.attrs.keys())} against {sorted(y.attrs.keys())}")
                continue
            for key in x.attrs.keys():
                if (path, key) in run_attributes:
                    continue
                u, v = x.attrs[key], y.attrs[key]
                same = (np.asarray(u).tobytes() == np.asarray(v).tobytes()
                        if np.asarray(u).dtype.kind in "fiu" else np.array_equal(u, v))
                if not same:
                    fail(f"{what}: {path} attribute {key}: {u!r} against {v!r}")
        if datasets < 10:
            fail(f"{what}: only {datasets} datasets compared")
        threads = int(b["/meta"].attrs["threads"])
        if threads != processes * threads_each:
            fail(f"{what}: /meta threads = {threads}, expected {processes} × {threads_each}")

TAYLOR = """\
# The Duffing impact oscillator (experiments/examples/duffing_impact.yaml): a cubic spring, so
# the Taylor engine.
name: mpi-taylor
model:
  chain: {masses: [1], left_wall: {spring: 1, damper: 0.05}}
forcing: {frequency: 1.3, cosine: [0.8]}
stops:
  - {mass: 0, side: upper, position: 0.6, restitution: 0.8, name: stop}
parameters: {beta: 0.5}
forces:
  - {cubic_spring: {mass: 0, coefficient: beta}}
initial: {x: [0], v: [0]}
"""
TAYLOR_RUNS = {
    "sweep": """\
record:
  events: true
  statistics: true
  poincare: true
  samples: {per_period: 16}
run:
  kind: sweep
  transient_periods: 20
  periods: 3
  sweep:
    parameters:
      - {path: forcing.frequency, linspace: [0.8, 1.0, 5]}
      - {path: parameters.beta, values: [0, 0.5]}
""",
    "basin": """\
run:
  kind: basin
  basin:
    parameters:
      - {path: "initial.x[0]", linspace: [-1, 0.5, 5]}
      - {path: "initial.v[0]", linspace: [-1, 1, 5]}
    seed_stride: 2
""",
}


def write_scene(work, key):
    path = os.path.join(work, f"{key}.yaml")
    with open(path, "w") as f:
        f.write(BASE + SWEEPS[key])
    return path


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("case", choices=["plain", "follow", "resume", "basin", "errors", "taylor"])
    parser.add_argument("--vibro", required=True)
    parser.add_argument("--driver", required=True)
    parser.add_argument("--mpirun", required=True)
    parser.add_argument("--work", required=True)
    o = parser.parse_args()
    # A fresh directory per run: two test runs at once share nothing.
    os.makedirs(o.work, exist_ok=True)
    work = tempfile.mkdtemp(prefix=o.case + "-", dir=o.work)
    mpirun = [o.mpirun, "--oversubscribe", "-np", "2"]

    def reference(scene, out):
        expect([o.vibro, "run", scene, "-o", out, "--threads", "2"], f"one process: {scene}", 0)

    if o.case == "plain":
        scene = write_scene(work, "plain")
        one, many = os.path.join(work, "one.h5"), os.path.join(work, "many.h5")
        reference(scene, one)
        expect(mpirun + [o.vibro, "run", scene, "-o", many, "--threads", "1"], "mpirun -np 2", 0)
        compare(one, many, "plain sweep, 2 processes × 1 thread", 2, 1)
        # Two threads in each process as well (4 threads on 2 processes).
        many2 = os.path.join(work, "many2.h5")
        expect(mpirun + [o.vibro, "run", scene, "-o", many2, "--threads", "2"], "mpirun -np 2, 2 threads", 0)
        compare(one, many2, "plain sweep, 2 processes × 2 threads", 2, 2)
        with h5py.File(one, "r") as f:  # the scene must exercise every recorded group
            for group in ("events", "contacts", "samples", "poincare", "stats"):
                if group not in f:
                    fail(f"plain sweep: /{group} missing")
            kinds = set(f["events/kind"][()].tolist()) if "events" in f else set()
            if not {0, 2, 3} <= kinds:  # sticking starts at chatter limits here
                fail(f"plain sweep: event kinds {sorted(kinds)}, expected impacts, releases and chatter limits")
            if "contacts" in f and f["contacts/t_start"].shape[0] == 0:
                fail("plain sweep: no contact intervals")
    elif o.case == "follow":
        for key in ("follow1", "follow2"):
            scene = write_scene(work, key)
            one, many = os.path.join(work, f"{key}-one.h5"), os.path.join(work, f"{key}-many.h5")
            reference(scene, one)
            expect(mpirun + [o.vibro, "run", scene, "-o", many, "--threads", "1"], f"mpirun {key}", 0)
            compare(one, many, f"{key} sweep", 2, 1)
    elif o.case == "resume":
        # plain: 9 points, stopped after 3; follow2: rows of 3, stopped after 4 (inside row 2).
        for key, after in (("plain", 3), ("follow2", 4)):
            scene = write_scene(work, key)
            one, many = os.path.join(work, f"{key}-one.h5"), os.path.join(work, f"{key}-many.h5")
            reference(scene, one)
            expect(mpirun + [o.driver, scene, many, "1", str(after)], f"{key}: interrupted run", 130)
            if os.path.exists(many) or not os.path.exists(many + ".partial"):
                fail(f"{key}: after the interruption expected only {many}.partial")
                continue
            with h5py.File(many + ".partial", "r") as f:
                kept = int(f["/sweep"].attrs["completed"])
            if not after <= kept < (9 if key == "plain" else 12):
                fail(f"{key}: {kept} points kept after an interruption at {after}")
            expect(mpirun + [o.vibro, "run", scene, "-o", many, "--threads", "1", "--resume"], f"{key}: --resume", 0)
            compare(one, many, f"{key} sweep, interrupted and resumed under MPI", 2, 1,
                    RUN_ATTRIBUTES | {("/meta", "resumed")})
            with h5py.File(many, "r") as f:
                if int(f["/meta"].attrs["resumed"]) != 1:
                    fail(f"{key}: /meta resumed = {f['/meta'].attrs['resumed']} after --resume")
    elif o.case == "basin":
        scene = os.path.join(work, "basin.yaml")
        with open(scene, "w") as f:
            f.write(BASIN)
        one, many = os.path.join(work, "basin-one.h5"), os.path.join(work, "basin-many.h5")
        reference(scene, one)
        expect(mpirun + [o.vibro, "run", scene, "-o", many, "--threads", "1"], "mpirun basin", 0)
        compare(one, many, "basin, 2 processes × 1 thread", 2, 1)
        with h5py.File(one, "r") as f:
            if f["attractors/period"].shape[0] != 2:
                fail(f"basin: {f['attractors/period'].shape[0]} attractors, expected 2")
    elif o.case == "taylor":
        for key, text in TAYLOR_RUNS.items():
            scene = os.path.join(work, f"taylor-{key}.yaml")
            with open(scene, "w") as f:
                f.write(TAYLOR + text)
            one, many = os.path.join(work, f"taylor-{key}-one.h5"), os.path.join(work, f"taylor-{key}-many.h5")
            reference(scene, one)
            expect(mpirun + [o.vibro, "run", scene, "-o", many, "--threads", "1"], f"mpirun taylor {key}", 0)
            compare(one, many, f"Taylor engine {key}, 2 processes × 1 thread", 2, 1)
            with h5py.File(one, "r") as f:
                if f["/meta"].attrs["engine"] != "taylor":
                    fail(f"taylor {key}: engine {f['/meta'].attrs['engine']}, expected taylor")
                if key == "sweep" and f["events/t"].shape[0] == 0:
                    fail("taylor sweep: no events")
    elif o.case == "errors":
        scene = write_scene(work, "plain")
        out = os.path.join(work, "out.h5")
        open(out + ".partial", "w").close()
        err = expect(mpirun + [o.vibro, "run", scene, "-o", out], "stale .partial", 3)
        if err.count("an interrupted sweep is kept there") != 1:
            fail(f"stale .partial: expected the message once, got:\n{err}")
        os.remove(out + ".partial")
        err = expect(mpirun + [o.vibro, "run", scene, "-o", out, "--set", "stops[1].position=-0.5"],
                     "invalid point", 2)
        if err.count("error:") != 1:
            fail(f"invalid point: expected one error message, got:\n{err}")
        if os.path.exists(out) or os.path.exists(out + ".partial"):
            fail("invalid input left a file")
    for f in FAILURES:
        print(f)
    if not FAILURES:
        shutil.rmtree(work, ignore_errors=True)
        print(f"{o.case}: MPI and one-process results agree")
    return 1 if FAILURES else 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Throughput of the study run kinds on the paper's system: basin, diagram and continuation points per second.

    /usr/bin/python3 tools/bench/study_throughput.py [--build build/release] [--rounds 5] [--threads 2]

Runs `vibro run` on three scenes of the repository, alternating them round by round (so that a
change of the machine's load falls on all three alike), and prints one table: per scene the number
of points, the median wall-clock time of the whole command (start to exit, the result file written)
over the rounds, its spread, and the points per second of the median run:

  basin     experiments/chaos/basin_wagg.yaml        256 × 256 starts, the period-1 and period-2 attractors
  diagram   experiments/chaos/bifurcation_wagg.yaml  401 values of Ω, followed up and down (802 points)
  continue  experiments/wagg2004/continuation.yaml   the main job's branch over Ω ∈ [0.24, 0.28]

Each run's point count is read from the run's own summary line, so a scene edited to another size
is reported as it is. A run that fails stops the benchmark with its message. tools/bench/report.sh
runs this as its last step and docs/performance.md quotes the table.
"""
import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

SCENES = [
    ("basin", "experiments/chaos/basin_wagg.yaml", r"Basin of \d+ x \d+ = (\d+) points"),
    ("diagram", "experiments/chaos/bifurcation_wagg.yaml", r"\((\d+) values, (\d+) directions"),
    ("continue", "experiments/wagg2004/continuation.yaml", r"branches, (\d+) points"),
]


def points_of(kind, pattern, text):
    m = re.search(pattern, text)
    if not m:
        raise RuntimeError(f"{kind}: no summary line matching {pattern!r} in the run's output")
    if kind == "diagram":
        return int(m.group(1)) * int(m.group(2))
    return int(m.group(1))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", default="build/release")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2, help="OMP_NUM_THREADS of every run (default 2)")
    args = ap.parse_args()
    vibro = os.path.join(args.build, "tools", "vibro", "vibro")
    if not os.access(vibro, os.X_OK):
        sys.exit(f"study_throughput.py: {vibro} not found (build the vibro target first)")
    env = dict(os.environ, OMP_NUM_THREADS=str(args.threads))
    started = time.time()
    load_before = f"{os.getloadavg()[0]:.2f}"
    walls = {kind: [] for kind, _, _ in SCENES}
    points = {}
    with tempfile.TemporaryDirectory(prefix="vibro-study-throughput-") as tmp:
        for r in range(args.rounds):
            for kind, scene, pattern in SCENES:
                out = os.path.join(tmp, f"{kind}.h5")
                t0 = time.perf_counter()
                run = subprocess.run([vibro, "run", scene, "-o", out, "--force"], env=env,
                                     capture_output=True, text=True)
                wall = time.perf_counter() - t0
                if run.returncode != 0:
                    sys.exit(f"study_throughput.py: {kind} ({scene}) exited {run.returncode}:\n{run.stderr}{run.stdout}")
                n = points_of(kind, pattern, run.stdout + run.stderr)
                if points.setdefault(kind, n) != n:
                    sys.exit(f"study_throughput.py: {kind} gave {n} points in round {r + 1}, {points[kind]} before")
                walls[kind].append(wall)
    print(f"{args.rounds} rounds alternating the three scenes, OMP_NUM_THREADS={args.threads}; "
          f"wall-clock time of the whole `vibro run` (result file written), median and range; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime(started))}, load {load_before} before, "
          f"{os.getloadavg()[0]:.2f} after")
    print(f"{'kind':<10}{'scene':<42}{'points':>8}{'median s':>11}{'min s':>9}{'max s':>9}{'points/s':>11}")
    for kind, scene, _ in SCENES:
        w = walls[kind]
        med = statistics.median(w)
        print(f"{kind:<10}{scene:<42}{points[kind]:>8}{med:>11.2f}{min(w):>9.2f}{max(w):>9.2f}"
              f"{points[kind] / med:>11.1f}")


if __name__ == "__main__":
    main()

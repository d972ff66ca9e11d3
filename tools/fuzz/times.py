#!/usr/bin/env python3
"""Where fuzz_run's time goes: sums the lines FUZZ_RUN_TIMES=FILE makes it write (tools/fuzz/fuzz_run.cpp,
class Times), per run kind and phase, and prints the mean cost of an input and the executions per second
it allows. docs/fuzzing.md quotes its output.

    FUZZ_RUN_TIMES=/tmp/t.txt build/fuzz/tools/fuzz/fuzz_run -runs=20000 corpus seeds ...
    python3 tools/fuzz/times.py /tmp/t.txt
"""
import collections
import sys

KINDS = ["simulate", "sweep", "locate", "continue", "basin", "diagram", "lyapunov", "orbit"]


def main(path):
    rows = [line.split() for line in open(path) if line.strip()]
    if not rows:
        sys.exit(f"times: {path}: no lines")
    per = collections.OrderedDict()
    for r in rows:
        kind = int(r[0])
        name = KINDS[kind] if 0 <= kind < len(KINDS) else "not run"
        a = per.setdefault(name, {"n": 0, "wall": 0.0, "cpu": 0.0, "phases": [0.0] * 8, "late": 0})
        a["n"] += 1
        a["wall"] += float(r[1])
        a["cpu"] += float(r[2])
        a["phases"] = [x + max(float(y), 0.0) for x, y in zip(a["phases"], r[3:11])]
        a["late"] += float(r[6]) >= 0.0
    n = len(rows)
    wall = sum(a["wall"] for a in per.values())
    cpu = sum(a["cpu"] for a in per.values())
    print(f"{n} inputs; per input {wall / n:.2f} ms of wall time ({1e3 * n / wall:.0f} exec/s), "
          f"{cpu / n:.2f} ms of CPU ({1e3 * n / cpu:.0f} exec/s on an idle core)")
    print(f"{'kind':9} {'inputs':>6} {'share':>6} {'wall ms':>8} {'cpu ms':>8} | CPU s: {'build':>6} {'short':>6} "
          f"{'early':>6} {'late':>6} | wall s: {'build':>6} {'short':>6} {'early':>6} {'late':>6} (late runs)")
    for name, a in sorted(per.items(), key=lambda kv: -kv[1]["cpu"]):
        ph = a["phases"]
        print(f"{name:9} {a['n']:6d} {a['n'] / n:6.1%} {a['wall'] / a['n']:8.2f} {a['cpu'] / a['n']:8.2f} |        "
              + " ".join(f"{x / 1e3:6.2f}" for x in ph[4:]) + " |         "
              + " ".join(f"{x / 1e3:6.2f}" for x in ph[:4]) + f" ({a['late']})")
    print("slowest inputs by CPU (kind, then the line's fields from the wall time on):")
    for r in sorted(rows, key=lambda r: -float(r[2]))[:8]:
        kind = int(r[0])
        print(f"  {KINDS[kind] if 0 <= kind < len(KINDS) else 'not run':9} " + " ".join(r[1:]))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else sys.exit(__doc__))

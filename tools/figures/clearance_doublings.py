"""The period doublings of the three-mass clearance chain's period-1 branch, located by continuation
(experiments/examples/three_mass_clearance_continuation.yaml, from the non-sticking orbit at Ω = 0.7
down to 0.3), against the brute-force diagram of the same scene over the same range
(experiments/examples/three_mass_clearance_diagram.yaml, up and down).

    /usr/bin/python3 tools/figures/clearance_doublings.py DIAGRAM.h5 CONTINUATION.h5

A doubling the diagram shows is a pair of neighbouring values of one sweep where the least period
goes from 1 to 2 (or back) and the period-2 points straddle the period-1 point continuously: the
mean of the two period-2 points (x of every mass at the stroboscopic phase) within `CONTINUOUS` of
the period-1 point at the neighbouring value, as at a doubling the period-2 orbit is born from the
period-1 one (a jump to a distant period-2 attractor, where the period-1 one ends at a fold or a
grazing, is listed but not required to be a doubling). Each such pair must hold a period doubling
located on the period-1 branch (branch 0) between its two values; the script fails otherwise, and
prints every change of period 1 ↔ 2 with what continuation located there. (Not told apart yet:
a diagram's period-1 attractor that is not the continued branch's orbit — a coexisting one, seen
in one sweep only — and a doubling whose slow transient, a multiplier near −1, shifts the
diagram's change by a grid step.)
"""

import sys

import h5py
import numpy as np

# How near the mean of the two period-2 points must lie to the neighbouring period-1 point for a
# change 1 ↔ 2 to be a doubling (x, the diagram's stroboscopic positions; the orbits' amplitudes
# are ~0.3, the grid step 5e-4 in Ω: a period-2 orbit born at a doubling differs from its parent
# by the square root of the distance, its mean by the distance itself, ~1e-3 here at most).
CONTINUOUS = 0.02


def fail(message):
    sys.stderr.write(f"error: {message}\n")
    sys.exit(1)


def main():
    if len(sys.argv) != 3:
        fail("usage: clearance_doublings.py DIAGRAM.h5 CONTINUATION.h5")
    with h5py.File(sys.argv[1], "r") as f:
        g = f["diagram"]
        W = g["parameter"][()]
        sweeps = {s: (g[f"x_{s}"][()], g[f"k_{s}"][()]) for s in ("up", "down")}
    with h5py.File(sys.argv[2], "r") as f:
        b = f["bifurcations"]
        names = [n.decode() if isinstance(n, bytes) else n for n in b["kind"].attrs["names"]]
        marks = [(names[int(k)], float(p), float(lo), float(hi), int(br), int(sm))
                 for k, p, lo, hi, br, sm in zip(b["kind"][()], b["p"][()], b["p_low"][()], b["p_high"][()],
                                                 b["branch"][()], b["smooth"][()])]
    doublings = sorted(p for n, p, _, _, br, sm in marks if n == "period_doubling" and br == 0 and sm)
    print(f"continuation: {len(doublings)} period doublings located on the period-1 branch: "
          + ", ".join(f"{p:.10f}" for p in doublings))
    missed, seen = [], 0
    for s, (x, k) in sweeps.items():
        for i in range(len(W) - 1):
            if sorted((int(k[i]), int(k[i + 1]))) != [1, 2]:
                continue
            one, two = (i, i + 1) if k[i] == 1 else (i + 1, i)
            p1 = x[one][-1]           # the period-1 point (every recorded point is it)
            p2 = x[two][-2:]          # the two points of the period-2 orbit
            jump = float(np.max(np.abs(p2.mean(axis=0) - p1)))
            lo, hi = min(W[i], W[i + 1]), max(W[i], W[i + 1])
            inside = [p for p in doublings if lo <= p <= hi]
            others = [f"{n} {p:.10f}" for n, p, _, _, br, _ in marks if br == 0 and n != "period_doubling" and lo <= p <= hi]
            continuous = jump <= CONTINUOUS
            seen += continuous
            verdict = (f"doubling located at {inside[0]:.10f}" if inside else
                       ("MISSED" if continuous else "a jump, not a doubling") +
                       (f" (located there: {', '.join(others)})" if others else ""))
            print(f"  sweep {s:4s}: period {int(k[i])} → {int(k[i + 1])} between Ω = {W[i]:.6f} and {W[i + 1]:.6f}, "
                  f"|mean of the period-2 points − period-1 point| = {jump:.1e}: {verdict}")
            if continuous and not inside:
                missed.append((lo, hi))
    print(f"diagram: {seen} changes of period 1 ↔ 2 that are doublings; {len(missed)} not located by continuation")
    if missed:
        fail("doublings the diagram shows that continuation did not locate: "
             + ", ".join(f"[{a:.6f}, {b:.6f}]" for a, b in missed))


if __name__ == "__main__":
    main()

"""Figures of the soft-impact oscillator (experiments/soft_impact): the brute-force diagram over ω
with the continued branches and their located bifurcations drawn over it.

    /usr/bin/python3 experiments/soft_impact/figures.py DIAGRAM.h5 CONTINUATION.h5 OUTDIR

(a) x(t0 + nT) of the diagram's stroboscopic points, up sweep (blue) and down sweep (orange), and
the continued branches' x at the same phase (vibro.plot.branch: one colour per period, stable solid,
unstable dashed, bifurcations marked by kind), the located bifurcations also as vertical lines;
(b) the least period k of both sweeps (0: not periodic within max_period). Drawn by
tools/figures/diagram_branch.py.

Checks (the script fails if one does not hold): every diagram value was reached; the first
branch's lowest grazing agrees with the closed form of the non-contacting orbit's grazing,
a/√((1 − ω²)² + (2ζω)²) = e, to 1e-9; the branch's stable period-1 orbits at the diagram's values
agree with the diagram's stable points (1e-6, the diagram's periodicity tolerance).

Prints the numbers the README quotes; writes OUTDIR/soft_impact.png and OUTDIR/soft_impact.pdf.
"""

import math
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tools", "figures"))
from common import fail, save  # noqa: E402
from diagram_branch import (branch_against_diagram, check_agreement, draw, print_sweeps,  # noqa: E402
                            read_continuation, read_diagram)

# The scenes' values (diagram.yaml, continuation.yaml): 2ζ, a, e.
TWO_ZETA, A, E = 0.02, 0.2, 1.0


def grazing_closed_form():
    """The two ω where a/√((1 − ω²)² + (2ζω)²) = e: W = ω² solves W² + (4ζ² − 2) W + 1 − (a/e)² = 0."""
    b = TWO_ZETA**2 - 2.0
    disc = math.sqrt(b * b - 4.0 * (1.0 - (A / E) ** 2))
    return math.sqrt((-b - disc) / 2.0), math.sqrt((-b + disc) / 2.0)


def main():
    if len(sys.argv) != 4:
        fail("usage: figures.py DIAGRAM.h5 CONTINUATION.h5 OUTDIR")
    dpath, cpath, out = sys.argv[1:]
    for p in (dpath, cpath):
        if not os.path.isfile(p):
            fail(f"{p}: no such file")
    os.makedirs(out, exist_ok=True)
    diag, cont = read_diagram(dpath), read_continuation(cpath)
    marks, bk = cont["marks"], cont["branch_k"]
    low, high = grazing_closed_form()
    graze0 = sorted(v for n, v, bb, _ in marks if n == "grazing" and bb == 0)
    if not graze0:
        fail(f"no grazing located on the first branch: {marks}")
    first_graze = graze0[0]
    if abs(first_graze - low) > 1e-9:
        fail(f"the first grazing {first_graze:.12f} is not the closed form's {low:.12f}")
    worst, compared = branch_against_diagram(diag, cont)

    fig, (a, c) = draw(dpath, cpath, cont, lower="k")
    a.axhline(E, color="0.3", lw=0.6)
    a.set_ylabel("x(t₀ + nT)")
    a.set_title("soft-impact oscillator x'' + 2ζx' + x + β(x − e)H(x − e) = a cos ωt, ζ = 0.01, β = 29, e = 1, a = 0.2")
    c.set_xlabel("ω (forcing.frequency)")
    save(fig, out, "soft_impact")
    print_sweeps(diag, "ω")
    print(f"continuation in ω: {len(cont['p'])} branch points on {len(bk)} branches (periods {sorted(set(int(q) for q in bk))}), "
          f"{cont['wall']:.2f} s wall")
    print(f"  non-contacting orbit's grazings, closed form: ω = {low:.12f} and {high:.12f}")
    print(f"  first grazing located at ω = {first_graze:.12f} (|Δ| = {abs(first_graze - low):.1e})")
    for n, v, bb, sm in marks:
        print(f"  {n:16s} ω = {v:.12f}  branch {bb} (k = {int(bk[bb])}){'' if sm else '  (bisection)'}")
    check_agreement(worst, compared)
    print(os.path.join(out, "soft_impact.png"))

if __name__ == "__main__":
    main()

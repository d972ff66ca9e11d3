"""Figures of the shaken impact oscillator (experiments/shaken): the brute-force diagram over Ω
with the continued branch, its fold and its grazing drawn over it.

    /usr/bin/python3 experiments/shaken/figures.py DIAGRAM.h5 CONTINUATION.h5 OUTDIR

(a) x(t0 + nT) of the diagram's stroboscopic points, up sweep (blue) and down sweep (orange), and
the continued branch's x at the same phase (vibro.plot.branch: stable solid, unstable dashed,
bifurcations marked by kind), the located fold and grazing also as vertical lines; (b) impacts per
period of both sweeps. Drawn by tools/figures/diagram_branch.py.

Checks (the script fails if one does not hold): every diagram value was reached; the up sweep
leaves the impacting orbit between two grid values that bracket the located fold; the down sweep
lands on the impacting orbit within two grid steps of the located grazing (below the grazing the
non-impacting orbit is gone; just above it its clearance is so small that a sweep's transient can
touch the stop and be captured by the coexisting impacting orbit); the branch's orbits at the
diagram's values agree with the diagram's stable points where the branch is stable.

Prints the numbers the README quotes; writes OUTDIR/shaken.png and OUTDIR/shaken.pdf.
"""

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tools", "figures"))
import numpy as np  # noqa: E402
from common import fail, save  # noqa: E402
from diagram_branch import (branch_against_diagram, check_agreement, draw, print_sweeps,  # noqa: E402
                            read_continuation, read_diagram)


def main():
    if len(sys.argv) != 4:
        fail("usage: figures.py DIAGRAM.h5 CONTINUATION.h5 OUTDIR")
    dpath, cpath, out = sys.argv[1:]
    for p in (dpath, cpath):
        if not os.path.isfile(p):
            fail(f"{p}: no such file")
    os.makedirs(out, exist_ok=True)
    diag, cont = read_diagram(dpath), read_continuation(cpath)
    W, marks = diag["W"], cont["marks"]
    folds = [v for n, v, _, _ in marks if n == "fold"]
    grazings = [v for n, v, _, _ in marks if n == "grazing"]
    if len(folds) != 1 or len(grazings) != 1:
        fail(f"expected one fold and one grazing, found {marks}")
    fold, graze = folds[0], grazings[0]
    step = W[1] - W[0]

    # The up sweep's last impacting value below the fold and first non-impacting one above it.
    imp_up = diag["sweeps"]["up"]["impacts"]
    above = np.nonzero((W > 1.5) & (imp_up == 0))[0]
    if len(above) == 0:
        fail("the up sweep never leaves the impacting orbit above Ω = 1.5")
    jump_up = (W[above[0] - 1], W[above[0]])
    if not (jump_up[0] <= fold <= jump_up[1]):
        fail(f"the fold {fold} is not inside the up sweep's jump {jump_up}")
    imp_down = diag["sweeps"]["down"]["impacts"]
    free = np.nonzero((W > 1.0) & (W < 1.8) & (imp_down == 0))[0]
    if len(free) == 0:
        fail("the down sweep never runs without impacts in (1, 1.8)")
    jump_down = (W[free[0] - 1], W[free[0]])
    if abs(jump_down[0] - graze) > 2 * step:
        fail(f"the down sweep lands on the impacting orbit at {jump_down}, far from the grazing {graze}")
    worst, compared = branch_against_diagram(diag, cont)

    fig, (a, c) = draw(dpath, cpath, cont, lower="impacts")
    for n, v, _, _ in marks:
        a.text(v, -0.3, f" {n}\n Ω = {v:.6f}", fontsize=7, va="bottom")
    a.axhline(0.1, color="0.3", lw=0.6)
    a.set_ylabel("x(t₀ + nT) (rig frame)")
    a.set_title("impact oscillator on a shaken base, x_b = a cos Ωt + 0.3 a cos 2Ωt, a = 0.05, stop on the rig at 0.1")
    c.set_xlabel("Ω (forcing.frequency)")
    save(fig, out, "shaken")
    print_sweeps(diag, "Ω")
    print(f"continuation in Ω: {len(cont['p'])} branch points, {cont['wall']:.2f} s wall")
    print(f"  fold at Ω = {fold:.12f}; the up sweep leaves the impacting orbit between Ω = {jump_up[0]:.3f} and {jump_up[1]:.3f}")
    print(f"  grazing at Ω = {graze:.12f}; the down sweep lands on the impacting orbit at Ω = {jump_down[0]:.3f}"
          f" (free at {jump_down[1]:.3f})")
    check_agreement(worst, compared)
    print(os.path.join(out, "shaken.png"))

if __name__ == "__main__":
    main()

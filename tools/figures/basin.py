"""Basins of attraction (run.kind: basin; layout of /basin and /attractors in docs/results.md).

    python3 tools/figures/basin.py IN.h5 OUTDIR

Draws the label image over the two varied scene values (rows: /basin/p1, columns: /basin/p2),
one colour per attractor with a legend giving its period and share of the grid, grey for the
points that did not converge within the scene's period budget (chaotic, quasi-periodic or slow)
black for runs that stopped early and white for starts not run (an interrupted basin). Where both varied values are components of the initial
state (initial.x[i], initial.v[i]) the attractors' stroboscopic points are marked, projected onto
the plane (their other components differ from the grid's starts, so a mark need not lie in its
own colour).

Drawn by vibro.plot.basin (also white: starts outside a stop, not run).

Checks (the script fails if one does not hold): every label is −4 … −1 or an attractor's index;
the attractors' cell counts add up to the labelled points.

Writes OUTDIR/basin.png and OUTDIR/basin.pdf.
"""

import numpy as np

from common import args, fail, plt, save, vibro_module

vibro = vibro_module()


def main():
    (path,), outdir = args(1, 1, "IN.h5 OUTDIR")
    r = vibro.read(path)
    if "basin" not in r:
        fail(f"{path}: no /basin group (not a run.kind: basin file)")
    label, cells = r.basin.label, r.attractors.cells
    n_att = len(r.attractors.period)
    if label.min() < -4 or label.max() >= n_att:
        fail(f"labels outside [-4, {n_att - 1}]")
    for k in range(n_att):
        if np.count_nonzero(label == k) != cells[k]:
            fail(f"attractor {k}: {np.count_nonzero(label == k)} labelled points, /attractors/cells says {cells[k]}")
    fig, ax = plt.subplots(figsize=(5.2, 4.4))
    vibro.plot.basin(r, ax=ax)
    name = r.scene.attrs.get("name", "")
    omega = 2 * np.pi / float(r.scene.attrs["period"])
    wall = float(r.meta.get("wall_time", np.nan))
    mean_periods = float(r.basin.attrs["mean_periods"])
    ax.set_title(f"{name}: basins at $\\Omega$ = {omega:.4g}, {len(r.basin.p1)} x {len(r.basin.p2)} starts, "
                 f"mean {mean_periods:.1f} periods each" + (f", {wall:.0f} s" if np.isfinite(wall) else ""))
    print(save(fig, outdir, "basin"))


if __name__ == "__main__":
    main()

"""Brute-force bifurcation diagram (run.kind: diagram; layout of /diagram in docs/results.md).

    python3 tools/figures/bifurcation.py DIAGRAM.h5 [--transitions FILE.h5] [--mass J] OUTDIR

(a) x_J(t0 + nT) of the recorded stroboscopic points against the parameter, the up sweep (blue)
and the down sweep (orange, smaller) overlaid, so hysteresis and coexisting attractors show as
points of one colour only; (b) the detected least period k of each direction (0: not periodic
within max_period) and (c) the impacts per period. With --transitions, a locate file
(/transitions) or a continuation file (/bifurcations) marks every transition it found inside the
range with a vertical line, labelled by kind (folds and period doublings solid, the others
dotted).

Checks (the script fails if one does not hold): every point of a direction was reached; a point
whose period k is found repeats its stroboscopic x_J after k periods to the diagram's tolerance
scale (1e-4 of the range of x_J).

Writes OUTDIR/bifurcation.png and OUTDIR/bifurcation.pdf.
"""

import argparse
import os

import numpy as np

from common import fail, plt, save
import h5py

COLOURS = {"up": "tab:blue", "down": "tab:orange"}
SIZES = {"up": 2.0, "down": 0.7}


def transitions(path, lo, hi):
    """(parameter, kind name) of every transition in [lo, hi] of a locate or continuation file."""
    with h5py.File(path, "r") as f:
        if "transitions" in f:
            g, key = f["transitions"], "parameter"
        elif "bifurcations" in f:
            g, key = f["bifurcations"], "p"
        else:
            fail(f"{path}: neither /transitions (locate) nor /bifurcations (continue)")
        names = [n.decode() if isinstance(n, bytes) else n for n in g["kind"].attrs["names"]]
        out = [(float(p), names[int(k)]) for p, k in zip(g[key][()], g["kind"][()]) if lo <= p <= hi]
    return sorted(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("diagram")
    ap.add_argument("outdir")
    ap.add_argument("--transitions")
    ap.add_argument("--mass", type=int, default=1)
    o = ap.parse_args()
    for p in (o.diagram, o.transitions):
        if p and not os.path.isfile(p):
            fail(f"{p}: no such file")
    os.makedirs(o.outdir, exist_ok=True)
    with h5py.File(o.diagram, "r") as f:
        if "diagram" not in f:
            fail(f"{o.diagram}: no /diagram group (not a run.kind: diagram file)")
        g = f["diagram"]
        path = g.attrs["parameter"]
        directions = g.attrs["directions"].split()
        p = g["parameter"][()]
        data = {d: (g[f"x_{d}"][()], g[f"k_{d}"][()], g[f"impacts_{d}"][()], g[f"reached_{d}"][()])
                for d in directions}
        name = f["scene"].attrs.get("name", "")
        wall = float(f["meta"].attrs.get("wall_time", np.nan))
    j = o.mass
    span = max(np.ptp(np.concatenate([x[:, :, j].ravel() for x, _, _, _ in data.values()])), 1e-300)
    for d, (x, k, _, reached) in data.items():
        if not reached.all():
            fail(f"{d}: {np.count_nonzero(reached == 0)} points not reached")
        for i in np.nonzero(k > 0)[0]:
            xi = x[i, :, j]
            if np.max(np.abs(xi[k[i]:] - xi[:-k[i]])) > 1e-4 * span:
                fail(f"{d}: point {i} ({path} = {p[i]}) is said to have period {k[i]} but does not repeat")

    fig, axes = plt.subplots(3, 1, figsize=(7, 7.5), sharex=True, gridspec_kw={"height_ratios": [3, 1, 1]})
    a, b, c = axes
    for d, (x, k, imp, _) in data.items():
        P = x.shape[1]
        a.plot(np.repeat(p, P), x[:, :, j].ravel(), ".", ms=SIZES[d], color=COLOURS[d], label=f"sweep {d}",
               rasterized=True)
        b.plot(p, k, "-" if d == "up" else "--", color=COLOURS[d], lw=1, label=d)
        c.plot(p, imp, "-" if d == "up" else "--", color=COLOURS[d], lw=1, label=d)
    if o.transitions:
        marks = transitions(o.transitions, p.min(), p.max())
        shown = set()
        for q, kind in marks:
            style = "-" if kind in ("fold", "period_doubling", "period") else ":"
            for ax in axes:
                ax.axvline(q, color="0.5", lw=0.6, ls=style, zorder=0)
            if kind not in shown:
                shown.add(kind)
        a.text(0.01, 0.02, "vertical lines: " + ", ".join(sorted(shown)) + f" ({os.path.basename(o.transitions)})",
               transform=a.transAxes, fontsize=7, color="0.3")
    a.set_ylabel(f"$x_{{{j + 1}}}(t_0 + nT)$")
    a.legend(loc="upper right", markerscale=4)
    a.set_title(f"{name}: brute-force diagram, {len(p)} values, up and down"
                + (f", {wall:.1f} s" if np.isfinite(wall) else ""))
    b.set_ylabel("least period k\n(0: none)")
    c.set_ylabel("impacts\nper period")
    c.set_xlabel(path)
    print(save(fig, o.outdir, "bifurcation"))


if __name__ == "__main__":
    main()

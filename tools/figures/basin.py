"""Basins of attraction (run.kind: basin; layout of /basin and /attractors in docs/results.md).

    python3 tools/figures/basin.py IN.h5 OUTDIR

Draws the label image over the two varied scene values (rows: /basin/p1, columns: /basin/p2),
one colour per attractor with a legend giving its period and share of the grid, grey for the
points that did not converge within the scene's period budget (chaotic, quasi-periodic or slow)
black for runs that stopped early and white for starts not run (an interrupted basin). Where both varied values are components of the initial
state (initial.x[i], initial.v[i]) the attractors' stroboscopic points are marked, projected onto
the plane (their other components differ from the grid's starts, so a mark need not lie in its
own colour).

Checks (the script fails if one does not hold): every label is −3, −2, −1 or an attractor's index;
the attractors' cell counts add up to the labelled points.

Writes OUTDIR/basin.png and OUTDIR/basin.pdf.
"""

import re

import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.patches import Patch

from common import args, fail, plt, save
import h5py

ATTRACTOR_COLOURS = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
                     "tab:pink", "tab:olive", "tab:cyan"]


def state_component(path, x, v):
    """The attractor points' values of `path` if it is initial.x[i] or initial.v[i], else None."""
    m = re.fullmatch(r"initial\.([xv])\[(\d+)\]", path)
    if not m:
        return None
    return (x if m.group(1) == "x" else v)[:, int(m.group(2))]


def main():
    (path,), outdir = args(1, 1, "IN.h5 OUTDIR")
    with h5py.File(path, "r") as f:
        if "basin" not in f:
            fail(f"{path}: no /basin group (not a run.kind: basin file)")
        b, a = f["basin"], f["attractors"]
        label = b["label"][()]
        p1, p2 = b["p1"][()], b["p2"][()]
        path1, path2 = b.attrs["p1"], b.attrs["p2"]
        mean_periods = float(b.attrs["mean_periods"])
        period, first, cells = a["period"][()], a["first"][()], a["cells"][()]
        ax_, av_ = a["x"][()], a["v"][()]
        name = f["scene"].attrs.get("name", "")
        omega = 2 * np.pi / float(f["scene"].attrs["period"])
        wall = float(f["meta"].attrs.get("wall_time", np.nan))
    n_att = len(period)
    if label.min() < -3 or label.max() >= n_att:
        fail(f"labels outside [-3, {n_att - 1}]")
    for k in range(n_att):
        if np.count_nonzero(label == k) != cells[k]:
            fail(f"attractor {k}: {np.count_nonzero(label == k)} labelled points, /attractors/cells says {cells[k]}")

    colours = ["white", "black", "0.75"] + [ATTRACTOR_COLOURS[k % len(ATTRACTOR_COLOURS)] for k in range(n_att)]
    image = label + 3  # −3 → 0 (white), −2 → 1 (black), −1 → 2 (grey), k → k + 3
    fig, ax = plt.subplots(figsize=(5.2, 4.4))
    dx = (p2[-1] - p2[0]) / max(len(p2) - 1, 1) / 2
    dy = (p1[-1] - p1[0]) / max(len(p1) - 1, 1) / 2
    ax.imshow(image, origin="lower", cmap=ListedColormap(colours), vmin=-0.5, vmax=len(colours) - 0.5,
              extent=[p2[0] - dx, p2[-1] + dx, p1[0] - dy, p1[-1] + dy], aspect="auto", interpolation="nearest")
    handles = []
    total = label.size
    for k in range(n_att):
        share = 100.0 * cells[k] / total
        handles.append(Patch(color=colours[k + 3], label=f"attractor {k}: period {period[k]} ({share:.1f} %)"))
        rows = slice(first[k], first[k] + period[k])
        c1 = state_component(path1, ax_[rows], av_[rows])
        c2 = state_component(path2, ax_[rows], av_[rows])
        if c1 is not None and c2 is not None:
            ax.plot(c2, c1, "o", ms=5, mfc=colours[k + 3], mec="black", mew=0.8)
    for code, text in ((-1, "not converged"), (-2, "stopped early"), (-3, "not run (interrupted)")):
        n = np.count_nonzero(label == code)
        if n:
            handles.append(Patch(facecolor=colours[code + 3], edgecolor="0.5", label=f"{text} ({100.0 * n / total:.1f} %)"))
    ax.legend(handles=handles, loc="upper right", framealpha=0.9)
    ax.set_xlabel(path2)
    ax.set_ylabel(path1)
    ax.set_title(f"{name}: basins at $\\Omega$ = {omega:.4g}, {len(p1)} x {len(p2)} starts, "
                 f"mean {mean_periods:.1f} periods each" + (f", {wall:.0f} s" if np.isfinite(wall) else ""))
    print(save(fig, outdir, "basin"))


if __name__ == "__main__":
    main()

"""Figures of the shaken impact oscillator (experiments/shaken): the brute-force diagram over Ω
with the continued branch, its fold and its grazing drawn over it.

    /usr/bin/python3 experiments/shaken/figures.py DIAGRAM.h5 CONTINUATION.h5 OUTDIR

(a) x(t0 + nT) of the diagram's stroboscopic points, up sweep (blue) and down sweep (orange), and
the continued branch's x at the same phase (black: stable, grey dashed: unstable), the located
fold and grazing as vertical lines; (b) impacts per period of both sweeps.

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

import matplotlib

matplotlib.use("Agg")
import h5py  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

plt.rcParams.update({"font.size": 9, "axes.titlesize": 9, "legend.fontsize": 8, "savefig.dpi": 150, "figure.dpi": 150})


def fail(message):
    sys.stderr.write(f"error: {message}\n")
    sys.exit(1)


def main():
    if len(sys.argv) != 4:
        fail("usage: figures.py DIAGRAM.h5 CONTINUATION.h5 OUTDIR")
    dpath, cpath, out = sys.argv[1:]
    for p in (dpath, cpath):
        if not os.path.isfile(p):
            fail(f"{p}: no such file")
    os.makedirs(out, exist_ok=True)
    with h5py.File(dpath, "r") as f:
        g = f["diagram"]
        W = g["parameter"][()]
        d = {s: (g[f"x_{s}"][()][:, :, 0], g[f"k_{s}"][()], g[f"impacts_{s}"][()], g[f"reached_{s}"][()])
             for s in ("up", "down")}
        dwall = float(f["meta"].attrs.get("wall_time", np.nan))
    with h5py.File(cpath, "r") as f:
        b = f["branch"]
        p, x, stable, k = b["p"][()], b["x"][()][:, 0], b["stable"][()], b["k"][()]
        phase = b["phase"][()]
        bif = f["bifurcations"]
        names = [n.decode() if isinstance(n, bytes) else n for n in bif["kind"].attrs["names"]]
        marks = [(names[int(q)], float(v)) for q, v in zip(bif["kind"][()], bif["p"][()])]
        cwall = float(f["meta"].attrs.get("wall_time", np.nan))
    if np.any(phase != 0.0):
        fail("the branch's section is not at phase 0 (the diagram's stroboscopic phase)")
    for s, (_, _, _, reached) in d.items():
        if not reached.all():
            fail(f"{s}: {np.count_nonzero(reached == 0)} diagram values not reached")
    folds = [v for n, v in marks if n == "fold"]
    grazings = [v for n, v in marks if n == "grazing"]
    if len(folds) != 1 or len(grazings) != 1:
        fail(f"expected one fold and one grazing, found {marks}")
    fold, graze = folds[0], grazings[0]
    step = W[1] - W[0]

    # The up sweep's last impacting value below the fold and first non-impacting one above it.
    imp_up = d["up"][2]
    above = np.nonzero((W > 1.5) & (imp_up == 0))[0]
    if len(above) == 0:
        fail("the up sweep never leaves the impacting orbit above Ω = 1.5")
    jump_up = (W[above[0] - 1], W[above[0]])
    if not (jump_up[0] <= fold <= jump_up[1]):
        fail(f"the fold {fold} is not inside the up sweep's jump {jump_up}")
    imp_down = d["down"][2]
    free = np.nonzero((W > 1.0) & (W < 1.8) & (imp_down == 0))[0]
    if len(free) == 0:
        fail("the down sweep never runs without impacts in (1, 1.8)")
    jump_down = (W[free[0] - 1], W[free[0]])
    if abs(jump_down[0] - graze) > 2 * step:
        fail(f"the down sweep lands on the impacting orbit at {jump_down}, far from the grazing {graze}")
    # Stable branch orbits of period 1 against the diagram's points at the nearest grid value.
    worst, compared = 0.0, 0
    for pi, xi, si, ki in zip(p, x, stable, k):
        i = int(np.argmin(np.abs(W - pi)))
        if si != 1 or ki != 1 or abs(W[i] - pi) > 1e-9:
            continue
        cands = [d[s][0][i] for s in ("up", "down") if d[s][1][i] == 1]
        if cands:
            worst = max(worst, min(np.max(np.abs(c - xi)) for c in cands))
            compared += 1

    fig, (a, c) = plt.subplots(2, 1, figsize=(7, 6.2), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    for s, col, ms in (("up", "tab:blue", 2.0), ("down", "tab:orange", 0.8)):
        xs = d[s][0]
        a.plot(np.repeat(W, xs.shape[1]), xs.ravel(), ".", ms=ms, color=col, label=f"diagram, sweep {s}", rasterized=True)
        c.plot(W, d[s][2], "-" if s == "up" else "--", color=col, lw=1, label=s)
    # The branch in stable and unstable pieces.
    cut = np.nonzero(np.diff(stable) != 0)[0] + 1
    for lo, hi in zip(np.r_[0, cut], np.r_[cut, len(p)]):
        seg = slice(max(lo - 1, 0), hi)
        st = stable[lo] == 1
        a.plot(p[seg], x[seg], "-" if st else "--", color="black" if st else "0.55", lw=1.0,
               label=None)
    a.plot([], [], "-", color="black", label="continued branch, stable")
    a.plot([], [], "--", color="0.55", label="continued branch, unstable")
    for n, v in marks:
        for ax in (a, c):
            ax.axvline(v, color="tab:red" if n == "fold" else "tab:green", lw=0.7, ls=":")
        a.text(v, -0.3, f" {n}\n Ω = {v:.6f}", fontsize=7, va="bottom",
               color="tab:red" if n == "fold" else "tab:green")
    a.axhline(0.1, color="0.3", lw=0.6)
    a.set_ylabel("x(t₀ + nT) (rig frame)")
    a.legend(loc="lower left", markerscale=4, fontsize=7)
    a.set_title("impact oscillator on a shaken base, x_b = a cos Ωt + 0.3 a cos 2Ωt, a = 0.05, stop on the rig at 0.1")
    c.set_ylabel("impacts\nper period")
    c.set_xlabel("Ω (forcing.frequency)")
    c.legend(loc="upper right")
    for ext in ("png", "pdf"):
        fig.savefig(os.path.join(out, f"shaken.{ext}"), bbox_inches="tight")
    print(f"diagram: {len(W)} values of Ω in [{W[0]:g}, {W[-1]:g}], up and down, {dwall:.2f} s wall")
    for s in ("up", "down"):
        kk = d[s][1]
        print(f"  sweep {s}: {np.count_nonzero(kk == 1)} period-1, {np.count_nonzero(kk > 1)} of period 2..8, "
              f"{np.count_nonzero(kk == 0)} not periodic within 8 periods")
    print(f"continuation in Ω: {len(p)} branch points, {cwall:.2f} s wall")
    print(f"  fold at Ω = {fold:.12f}; the up sweep leaves the impacting orbit between Ω = {jump_up[0]:.3f} and {jump_up[1]:.3f}")
    print(f"  grazing at Ω = {graze:.12f}; the down sweep lands on the impacting orbit at Ω = {jump_down[0]:.3f}"
          f" (free at {jump_down[1]:.3f})")
    print(f"  stable period-1 branch points on diagram values: {compared}, max |x_branch − x_diagram| = {worst:.2e}")
    if compared == 0:
        fail("no stable branch point fell on a diagram value")
    if worst > 1e-6:
        fail(f"branch and diagram disagree by {worst:.2e} (> 1e-6, the diagram's periodicity tolerance)")
    print(os.path.join(out, "shaken.png"))


if __name__ == "__main__":
    main()

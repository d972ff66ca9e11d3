"""Figures of the soft-impact oscillator (experiments/soft_impact): the brute-force diagram over ω
with the continued branches and their located bifurcations drawn over it.

    /usr/bin/python3 experiments/soft_impact/figures.py DIAGRAM.h5 CONTINUATION.h5 OUTDIR

(a) x(t0 + nT) of the diagram's stroboscopic points, up sweep (blue) and down sweep (orange), and
the continued branches' x at the same phase (black: stable, grey dashed: unstable), the located
bifurcations as vertical lines; (b) the least period k of both sweeps (0: not periodic within
max_period).

Checks (the script fails if one does not hold): every diagram value was reached; the first
branch's lowest grazing agrees with the closed form of the non-contacting orbit's grazing,
a/√((1 − ω²)² + (2ζω)²) = e, to 1e-9; the branch's stable period-1 orbits at the diagram's values
agree with the diagram's stable points (1e-6, the diagram's periodicity tolerance).

Prints the numbers the README quotes; writes OUTDIR/soft_impact.png and OUTDIR/soft_impact.pdf.
"""

import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import h5py  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

plt.rcParams.update({"font.size": 9, "axes.titlesize": 9, "legend.fontsize": 8, "savefig.dpi": 150, "figure.dpi": 150})

# The scenes' values (diagram.yaml, continuation.yaml): 2ζ, a, e.
TWO_ZETA, A, E = 0.02, 0.2, 1.0
COLOURS = {"fold": "tab:red", "grazing": "tab:green", "period_doubling": "tab:purple", "neimark_sacker": "tab:brown"}


def fail(message):
    sys.stderr.write(f"error: {message}\n")
    sys.exit(1)


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
    with h5py.File(dpath, "r") as f:
        g = f["diagram"]
        W = g["parameter"][()]
        d = {s: (g[f"x_{s}"][()][:, :, 0], g[f"k_{s}"][()], g[f"reached_{s}"][()]) for s in ("up", "down")}
        dwall = float(f["meta"].attrs.get("wall_time", np.nan))
    with h5py.File(cpath, "r") as f:
        b = f["branch"]
        br, p, x, stable, k = b["branch"][()], b["p"][()], b["x_fixed"][()][:, 0], b["stable"][()], b["k"][()]
        ok = b["fixed_ok"][()]
        fixed_phase = float(b.attrs.get("fixed_phase", 0.0))
        bif = f["bifurcations"]
        names = [n.decode() if isinstance(n, bytes) else n for n in bif["kind"].attrs["names"]]
        marks = [(names[int(q)], float(v), int(bb), int(sm))
                 for q, v, bb, sm in zip(bif["kind"][()], bif["p"][()], bif["branch"][()], bif["smooth"][()])]
        branches = f["branches"]
        bk = branches["k"][()]
        cwall = float(f["meta"].attrs.get("wall_time", np.nan))
    if fixed_phase != 0.0:
        fail("the branch's fixed phase is not 0 (the diagram's stroboscopic phase)")
    for s, (_, _, reached) in d.items():
        if not reached.all():
            fail(f"{s}: {np.count_nonzero(reached == 0)} diagram values not reached")
    low, high = grazing_closed_form()
    graze0 = sorted(v for n, v, bb, _ in marks if n == "grazing" and bb == 0)
    if not graze0:
        fail(f"no grazing located on the first branch: {marks}")
    first_graze = graze0[0]
    if abs(first_graze - low) > 1e-9:
        fail(f"the first grazing {first_graze:.12f} is not the closed form's {low:.12f}")

    # Stable period-1 branch points against the diagram's points at the nearest grid value.
    worst, compared = 0.0, 0
    for bi, pi, xi, si, ki, oki in zip(br, p, x, stable, k, ok):
        i = int(np.argmin(np.abs(W - pi)))
        if si != 1 or ki != 1 or oki != 1 or abs(W[i] - pi) > 1e-9:
            continue
        cands = [d[s][0][i] for s in ("up", "down") if d[s][1][i] == 1]
        if cands:
            worst = max(worst, min(np.max(np.abs(c - xi)) for c in cands))
            compared += 1

    fig, (a, c) = plt.subplots(2, 1, figsize=(7, 6.2), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    for s, col, ms in (("up", "tab:blue", 2.0), ("down", "tab:orange", 0.8)):
        xs = d[s][0]
        a.plot(np.repeat(W, xs.shape[1]), xs.ravel(), ".", ms=ms, color=col, label=f"diagram, sweep {s}", rasterized=True)
        c.plot(W, d[s][1], "-" if s == "up" else "--", color=col, lw=1, label=s)
    for bi in np.unique(br):
        rows = np.nonzero((br == bi) & (ok == 1))[0]
        if len(rows) == 0:
            continue
        pp, xx, ss = p[rows], x[rows], stable[rows]
        cut = np.nonzero(np.diff(ss) != 0)[0] + 1
        for lo, hi in zip(np.r_[0, cut], np.r_[cut, len(pp)]):
            seg = slice(max(lo - 1, 0), hi)
            st = ss[lo] == 1
            a.plot(pp[seg], xx[seg], "-" if st else "--", color="black" if st else "0.55", lw=0.9)
    a.plot([], [], "-", color="black", label="continued branches, stable")
    a.plot([], [], "--", color="0.55", label="continued branches, unstable")
    seen = set()
    for n, v, bb, sm in marks:
        col = COLOURS.get(n, "0.4")
        for ax in (a, c):
            ax.axvline(v, color=col, lw=0.6, ls=":")
        if n not in seen:
            a.plot([], [], ":", color=col, label=n.replace("_", " "))
            seen.add(n)
    a.axhline(E, color="0.3", lw=0.6)
    a.set_ylabel("x(t₀ + nT)")
    a.legend(loc="lower right", markerscale=4, fontsize=7)
    a.set_title("soft-impact oscillator x'' + 2ζx' + x + β(x − e)H(x − e) = a cos ωt, ζ = 0.01, β = 29, e = 1, a = 0.2")
    c.set_ylabel("period k\n(0: none ≤ 8)")
    c.set_xlabel("ω (forcing.frequency)")
    c.legend(loc="upper right")
    for ext in ("png", "pdf"):
        fig.savefig(os.path.join(out, f"soft_impact.{ext}"), bbox_inches="tight")
    print(f"diagram: {len(W)} values of ω in [{W[0]:g}, {W[-1]:g}], up and down, {dwall:.2f} s wall")
    for s in ("up", "down"):
        kk = d[s][1]
        print(f"  sweep {s}: {np.count_nonzero(kk == 1)} period-1, {np.count_nonzero(kk > 1)} of period 2..8, "
              f"{np.count_nonzero(kk == 0)} not periodic within 8 periods")
    print(f"continuation in ω: {len(p)} branch points on {len(bk)} branches (periods {sorted(set(int(q) for q in bk))}), "
          f"{cwall:.2f} s wall")
    print(f"  non-contacting orbit's grazings, closed form: ω = {low:.12f} and {high:.12f}")
    print(f"  first grazing located at ω = {first_graze:.12f} (|Δ| = {abs(first_graze - low):.1e})")
    for n, v, bb, sm in marks:
        print(f"  {n:16s} ω = {v:.12f}  branch {bb} (k = {int(bk[bb])}){'' if sm else '  (bisection)'}")
    print(f"  stable period-1 branch points on diagram values: {compared}, max |x_branch − x_diagram| = {worst:.2e}")
    if compared == 0:
        fail("no stable branch point fell on a diagram value")
    if worst > 1e-6:
        fail(f"branch and diagram disagree by {worst:.2e} (> 1e-6, the diagram's periodicity tolerance)")
    print(os.path.join(out, "soft_impact.png"))


if __name__ == "__main__":
    main()

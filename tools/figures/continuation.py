"""The paper's branch of periodic orbits in Ω by continuation (run.kind: continue), with every
located bifurcation, and the orbits that coexist where the branch folds.

(a) each stop's sticking fraction along the branch, stable parts solid and unstable parts dashed,
    located bifurcations marked (▲ rising, ● grazing, ◆ fold, ■ phase/chatter change, ✕ other);
(b), (c) zooms on the two stretches where the branch folds (Ω ≈ 0.2574–0.2594, where mass 1's
    bounces after its split sticking phase vanish one by one at grazings, each with a fold, and
    Ω ≈ 0.2637, where mass 1 loses an impact per period);
and a second figure with the two stable orbits that coexist between the grazing corner and the
fold near Ω ≈ 0.2637: each run with the vibro Python module (from the build tree) for 200 periods
from its branch point, then drawn over two periods; the script fails if they do not stay apart.

    vibro run experiments/wagg2004/continuation.yaml -o continuation.h5
    python3 tools/figures/continuation.py continuation.h5 experiments/wagg2004/continuation.yaml BUILD_DIR OUTDIR

Any other scene's branch: `continuation.py --name NAME FILE.h5 SCENE.yaml BUILD_DIR OUTDIR` draws (a),
its largest multiplier over the whole range and a zoom on the stretch with the most bifurcations.
"""
import os
import sys

import common as c
import h5py
import matplotlib.pyplot as plt
import numpy as np

MARKERS = {"rising": "^", "grazing": "o", "fold": "D", "period_doubling": "s", "neimark_sacker": "*",
           "phase_change": "s", "chatter_change": "s", "other": "x", "branch_point": "P"}


def read(path):
    with h5py.File(path, "r") as f:
        c.check_status(f, path)
        b = {k: f["branch"][k][()] for k in f["branch"]}
        bi = {k: f["bifurcations"][k][()] for k in f["bifurcations"]}
        names = [n.decode() if isinstance(n, bytes) else n for n in f["bifurcations/kind"].attrs["names"]]
        scene = c.read_scene(f)
        param = f["branch"].attrs["parameter"]
        param = param.decode() if isinstance(param, bytes) else param
    bi["kind_name"] = [names[int(k)] for k in bi["kind"]]
    return b, bi, scene, param


def draw_branch(ax, b, y, colour, label=None):
    """y along the branch in order of arclength, solid where stable, dashed where not."""
    p, stable = b["p"], b["stable"].astype(bool)
    for i in range(len(p) - 1):
        if b["branch"][i] != b["branch"][i + 1]:
            continue
        both = stable[i] and stable[i + 1]
        ax.plot(p[i:i + 2], y[i:i + 2], "-" if both else "--", color=colour, lw=1.0 if both else 0.8,
                label=label if (label and i == 0) else None)


def mark(ax, bi, b, stop_of_y, y_of_point, xlim=None):
    for i, kind in enumerate(bi["kind_name"]):
        p = bi["p"][i]
        if xlim and not (xlim[0] <= p <= xlim[1]):
            continue
        j = int(bi["stop"][i])
        if j >= 0 and stop_of_y is not None and j != stop_of_y:
            continue
        # The point's y: the nearest branch point's (located points are on the branch).
        k = int(np.argmin(np.abs(b["p"] - p)))
        ax.plot([p], [y_of_point(k)], MARKERS.get(kind, "x"), ms=4, mfc="none" if kind == "grazing" else None,
                color="k")


def coexistence(build, scene_file, outdir, b, bi, param, scene):
    """The two stable orbits between the grazing corner and the fold near Ω = 0.2637."""
    sys.path.insert(0, os.path.join(build, "python"))
    try:
        import vibro
    except ImportError as e:
        c.fail(f"the vibro Python module is not in {build}/python ({e}): build first")
    kinds = bi["kind_name"]
    folds = [i for i, k in enumerate(kinds) if k == "fold" and 0.2636 < bi["p"][i] < 0.2640]
    grazes = [i for i, k in enumerate(kinds) if k == "grazing" and 0.2636 < bi["p"][i] < 0.2640]
    if not folds or not grazes:
        c.fail("no fold and grazing near Ω = 0.2637 in the continuation file")
    lo, hi = bi["p"][grazes[0]], bi["p"][folds[0]]
    if not lo < hi:
        c.fail(f"the grazing corner ({lo}) is not below the fold ({hi})")
    omega = 0.5 * (lo + hi)
    # The stable branch points nearest omega with and without mass 1's impact.
    sig = b["signature"]
    with_impact, without = None, None
    for i in range(len(b["p"])):
        if not b["stable"][i] or b["located"][i]:
            continue
        slot = "with" if sig[i][0] > 0 else "without"
        cur = with_impact if slot == "with" else without
        if cur is None or abs(b["p"][i] - omega) < abs(b["p"][cur] - omega):
            if slot == "with":
                with_impact = i
            else:
                without = i
    if with_impact is None or without is None:
        c.fail("no stable branch points on both sides of the bistable window")
    orbits = []
    for i, label in ((with_impact, "with mass 1's impact"), (without, "without it")):
        s = vibro.Scene.load(scene_file)
        s.set(param, omega)
        s.set("initial.time", float(b["t0"][i]))
        for m in range(len(b["x"][i])):
            s.set(f"initial.x[{m}]", float(b["x"][i][m]))
            s.set(f"initial.v[{m}]", float(b["v"][i][m]))
        r = vibro.simulate(s, transient_periods=200, periods=2, samples=400)
        orbits.append((label, r))
    # They must stay apart (two attractors) and each be periodic after its transient.
    xa, xb = orbits[0][1].samples.x, orbits[1][1].samples.x
    if np.max(np.abs(xa - xb)) < 1e-3:
        c.fail("the two runs converged to one orbit: no coexistence")
    for label, r in orbits:
        n = len(r.samples.t) // 2
        if np.max(np.abs(r.samples.x[:n] - r.samples.x[n:2 * n])) > 1e-8:
            c.fail(f"the orbit {label} is not periodic after its transient")
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for (label, r), style in zip(orbits, ("-", "--")):
        for m, ax in enumerate(axes):
            ax.plot(r.samples.x[:, m], r.samples.v[:, m], style, lw=0.9, label=label)
    axes[0].axvline(-0.3, color="k", lw=0.6)
    axes[1].axvline(0.1, color="k", lw=0.6)
    for m, ax in enumerate(axes):
        ax.set(xlabel=c.mass_label(m), ylabel=c.velocity_label(m))
    axes[0].legend(loc="best")
    fig.suptitle(f"Two stable period-1 orbits at Ω = {omega:.7f} (between the grazing corner "
                 f"{lo:.9f} and the fold {hi:.9f})")
    out = c.save(fig, outdir, "continuation_coexistence")
    print(f"coexisting stable orbits at Omega = {omega:.9f}: {out}")


def densest_window(bi, lo, hi):
    """The stretch of a tenth of [lo, hi] holding the most located bifurcations."""
    width = 0.1 * (hi - lo)
    ps = np.sort(np.asarray(bi["p"]))
    if len(ps) == 0:
        return lo, lo + width
    counts = [np.count_nonzero((ps >= p) & (ps <= p + width)) for p in ps]
    start = ps[int(np.argmax(counts))]
    pad = 0.1 * width
    return start - pad, start + width - pad


def main():
    a = sys.argv[1:]
    name = None
    if len(a) >= 2 and a[0] == "--name":
        name, a = a[1], a[2:]
    if len(a) != 4:
        c.fail("usage: continuation.py [--name NAME] CONTINUATION.h5 SCENE.yaml BUILD_DIR OUTDIR")
    path, scene_file, build, outdir = a
    # The paper's system (two masses, stops s1 and s2) gets its two fold stretches zoomed and its
    # coexisting orbits drawn; any other scene (--name) its branch, its largest multiplier over
    # the whole range and a zoom on the stretch with the most bifurcations.
    paper = name is None
    os.makedirs(outdir, exist_ok=True)
    b, bi, scene, param = read(path)
    if not np.all(b["residual"] < 1e-8):
        c.fail("a branch point is not periodic to 1e-8")
    stick = b["sticking_fraction"]
    radius = np.maximum(b["spectral_radius"], 1e-6)

    fig = plt.figure(figsize=(11, 7.2))
    grid = fig.add_gridspec(2, 2, height_ratios=[1.3, 1])
    ax_a = fig.add_subplot(grid[0, :])
    ax_c, ax_d = fig.add_subplot(grid[1, 0]), fig.add_subplot(grid[1, 1])
    for j in range(stick.shape[1]):
        colour = c.STOP_COLOURS[j]
        draw_branch(ax_a, b, stick[:, j], colour, label=f"stop {scene.stop_name[j]} ({c.mass_label(int(scene.stop_mass[j]))})")
        mark(ax_a, bi, b, j, lambda k, j=j: stick[k, j])
    ax_a.set(xlabel="Ω", ylabel="sticking fraction of the period",
             title="(a) the branch in Ω: stable solid, unstable dashed; ▲ rising, ○ grazing, ◆ fold, ■ phase/chatter change")
    ax_a.legend(loc="upper left")
    lo_all, hi_all = float(np.min(b["p"])), float(np.max(b["p"]))
    windows = ((0.2573, 0.2595), (0.26365, 0.26385)) if paper else ((lo_all, hi_all), densest_window(bi, lo_all, hi_all))
    for ax, (lo, hi), tag in zip((ax_c, ax_d), windows, ("(b)", "(c)")):
        sel = (b["p"] >= lo) & (b["p"] <= hi)
        draw_branch(ax, {k: v[sel] for k, v in b.items()}, radius[sel], "k")
        mark(ax, bi, {k: v[sel] for k, v in b.items()}, None, lambda k: radius[sel][k], xlim=(lo, hi))
        ax.axhline(1.0, color="grey", lw=0.6, ls=":")
        ax.set(yscale="log", xlim=(lo, hi), xlabel="Ω", ylabel="largest |μ|",
               title=f"{tag} largest Floquet multiplier, Ω ∈ [{lo:.5g}, {hi:.5g}]")
        ax.ticklabel_format(axis="x", useOffset=False)
        ax.xaxis.set_major_locator(plt.MaxNLocator(4))
    fig.tight_layout()
    print(f"branch: {len(b['p'])} points, {len(bi['p'])} bifurcations: {c.save(fig, outdir, name or 'continuation')}")
    check_grazings(build, path)
    if paper:
        coexistence(build, scene_file, outdir, b, bi, param, scene)


def check_grazings(build, path):
    """Every located grazing's orbit, run for one period from its state with the vibro Python
    module, must come within 1e-9 (× its stop's position scale) of its stop in free flight: the
    orbit touches the stop there (two_parameter.nearest_approach, an independent sampling)."""
    sys.path.insert(0, os.path.join(build, "python"))
    import vibro
    import two_parameter
    with h5py.File(path, "r") as f:
        names = [n.decode() if isinstance(n, bytes) else n for n in f["bifurcations/kind"].attrs["names"]]
        for i in range(len(f["bifurcations/p"])):
            if names[int(f["bifurcations/kind"][i])] != "grazing" or not f["bifurcations/smooth"][i]:
                continue
            if f["scene/stop_kind"].attrs["names"][int(f["scene/stop_kind"][int(f["bifurcations/stop"][i])])] in (b"between", "between"):
                continue
            gap, scale, how = two_parameter.nearest_approach(vibro, f, i)
            p = f["bifurcations/p"][i]
            print(f"grazing at Ω = {p:.10f}: its orbit comes within {abs(gap):.1e} of the stop {how}")
            if abs(gap) > 1e-9 * max(scale, 1e-3):
                c.fail(f"the grazing located at Ω = {p:.10f} stays {gap:.1e} from its stop: not a grazing")


if __name__ == "__main__":
    main()

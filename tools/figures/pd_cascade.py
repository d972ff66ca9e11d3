"""A period-doubling cascade by continuation (experiments/examples/pd_cascade.yaml), checked
against a brute-force sweep.

The continuation file holds the period-1 branch and the branches of periods 2, 4, … switched onto
at each located period doubling. Each branch point is one state of its orbit at the section
(forcing phase 0); the orbit's other k − 1 section states are computed here by running the branch
point for k periods with the vibro Python module (from the build tree), so that each branch is
drawn with all its k prongs. A brute-force bifurcation diagram is run with the same module: a
sweep up in Ω with `follow` (each point from the previous one's final state), starting on the
period-1 orbit at the range's lower end, over a coarse grid of the whole range, two fine grids of
the cascade's end, and every stable branch point; after a transient of N periods it records R more
section states, drawn as dots.

Checks (the script fails if one does not hold):
  * every branch point is periodic to 1e-8 and the branches form one cascade (each branch
    switched from the previous at its located period doubling, period doubling each time);
  * at every stable branch point where the sweep's transient can have settled — the orbit
    attracts fast enough (ρ^(N/k) ≤ 1e-6, ρ its largest |μ| over kT) and the orbit of half its
    period, which the sweep followed up to the doubling, repels fast enough (R^(2N/k) ≥ 1e6): next to a doubling
    both are slow and a follow sweep lags — the sweep's state is k-periodic and its k section
    states are the orbit's to 1e-6 (relative to the range of x and of v along the branches): the
    stable branches lie on the sweep's points;
  * at every grid point inside such a stable stretch (both neighbouring branch points settle),
    the sweep's least period is that branch's k.

Figure pd_cascade: (a) the displacement of mass 2 at the section against Ω over the range,
branches coloured by period, stable solid, unstable dashed, period doublings □, sweep dots grey
(on the coarse grid); (b), (c) zooms on the cascade's end (one group of prongs each, the fine
grids); (d) along each branch, its real multiplier of largest modulus against the distance to the
estimated accumulation point Ω∞ (log scale): each doubled branch's starts at +1 where it is born
and leaves through −1 at its own doubling; (e) the spacings of successive doublings and their
ratios (Feigenbaum's δ = 4.6692…). Printed: the located doublings, spacings,
ratios and the checks' figures.

    vibro run experiments/examples/pd_cascade.yaml -o pd_cascade.h5
    python3 tools/figures/pd_cascade.py pd_cascade.h5 experiments/examples/pd_cascade.yaml BUILD_DIR OUTDIR
"""
import os
import sys
import time

import common as c
import h5py
import matplotlib.pyplot as plt
import numpy as np

FEIGENBAUM = 4.669201609102990
TRANSIENT = 300          # sweep: periods per point before recording
RECORDED = 64            # sweep: section states recorded per point (after the transient)
CONVERGED = 1e-6         # ρ^TRANSIENT at most this: the sweep has converged onto the orbit
MATCH = 1e-6             # sweep state vs branch orbit, relative to the branches' x and v ranges
COARSE = 0.001          # grid spacing over the whole range
FINE = [(1.7465, 1.7505, 2e-5), (1.7494, 1.7502, 2e-6)]   # grids on the cascade's end: from, to, spacing
# the zooms (b), (c): Ω range and x2 range (one group of prongs each)
ZOOMS = [((1.7465, 1.7505), (-0.63, -0.45)), ((1.7494, 1.7502), (-2.0, -1.925))]
COORD = 1                # the displacement drawn: mass 1 (the paper's numbering: x2)
K_COLOURS = ["black", "tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
             "tab:pink", "tab:olive"]


def read(path):
    with h5py.File(path, "r") as f:
        c.check_status(f, path)
        b = {k: f["branch"][k][()] for k in f["branch"]}
        br = {k: f["branches"][k][()] for k in f["branches"]}
        ends = f["branches/count"].attrs.get("end", f["branches"].attrs.get("end", []))
        br["end"] = [e.decode() if isinstance(e, bytes) else str(e) for e in ends]
        bi = {k: f["bifurcations"][k][()] for k in f["bifurcations"]}
        names = [n.decode() if isinstance(n, bytes) else n for n in f["bifurcations/kind"].attrs["names"]]
        param = f["branch"].attrs["parameter"]
        param = param.decode() if isinstance(param, bytes) else param
        scene = c.read_scene(f)
    bi["kind_name"] = [names[int(k)] for k in bi["kind"]]
    if param != "forcing.frequency":
        c.fail(f"{path}: continued in {param}, not forcing.frequency")
    return b, br, bi, scene


def start_scene(vibro, scene_file, omega, t0, x, v):
    s = vibro.Scene.load(scene_file)
    values = {"forcing.frequency": float(omega), "initial.time": float(t0)}
    for m in range(len(x)):
        values[f"initial.x[{m}]"] = float(x[m])
        values[f"initial.v[{m}]"] = float(v[m])
    s.update(values)
    return s


def orbit_states(vibro, scene_file, pts, lo, hi, what):
    """Per orbit (pts: p, t0, x, v, k, spectral_radius as in /branch or /bifurcations), its k
    section states (k × n each for x and v), by running k periods from the point (its own state
    first); the run must close the orbit."""
    xs, vs = [], []
    base = vibro.Scene.load(scene_file)
    n = pts["x"].shape[1]
    scale = max(np.max(np.abs(pts["x"])), 1e-300)
    for i in range(len(pts["p"])):
        k = int(pts["k"][i])
        s = base.copy()
        values = {"forcing.frequency": float(np.clip(pts["p"][i], lo, hi)), "initial.time": float(pts["t0"][i])}
        for m in range(n):
            values[f"initial.x[{m}]"] = float(pts["x"][i][m])
            values[f"initial.v[{m}]"] = float(pts["v"][i][m])
        s.update(values)
        r = vibro.simulate(s, transient_periods=0, periods=k, poincare=True, threads=1)
        if r.status != "completed":
            c.fail(f"{what} {i} (Ω = {pts['p'][i]}): the run from it stopped: {r.status}")
        px, pv = np.asarray(r.poincare.x), np.asarray(r.poincare.v)
        growth = max(float(pts["spectral_radius"][i]), 1.0) if "spectral_radius" in pts else 1.0
        miss = float(np.max(np.abs(px[k] - pts["x"][i])))
        if miss > 1e-9 * scale * growth:
            c.fail(f"{what} {i} (Ω = {pts['p'][i]}, k = {k}): the run from it does not close after kT ({miss:.1e})")
        xs.append(px[:k])
        vs.append(pv[:k])
    return xs, vs


def least_period(px, pv, xs, vs, tol, kmax):
    z = np.hstack([px / xs, pv / vs])
    for k in range(1, min(kmax, len(z) - 1) + 1):
        if np.max(np.abs(z[k:] - z[:-k])) <= tol:
            return k
    return 0


def draw_branches(ax, b, ox, bi, pd_x, colour_of_k, xlim=None):
    """Each branch's k prongs (the orbit's k section states) along Ω, solid where stable, dashed
    where not; the located period doublings as squares (all the orbit's section states there)."""
    for j in np.unique(b["branch"]):
        idx = np.where(b["branch"] == j)[0]
        k = int(b["k"][idx[0]])
        col = colour_of_k(k)
        stable = b["stable"][idx].astype(bool)
        Y = np.array([ox[i][:, COORD] for i in idx])      # points × k
        p = b["p"][idx]
        # runs of equal stability, each drawn as one polyline per prong (a run's last point is
        # the next run's first)
        a = 0
        while a < len(idx) - 1:
            e = a + 1
            seg_stable = stable[a] and stable[e]
            while e + 1 < len(idx) and (stable[e] and stable[e + 1]) == seg_stable:
                e += 1
            ax.plot(p[a:e + 1], Y[a:e + 1], "-" if seg_stable else "--", color=col,
                    lw=1.1 if seg_stable else 0.6)
            a = e
    for i, kind in enumerate(bi["kind_name"]):
        if kind != "period_doubling":
            continue
        p = bi["p"][i]
        if xlim and not (xlim[0] <= p <= xlim[1]):
            continue
        ax.plot(np.full(len(pd_x[i]), p), pd_x[i][:, COORD], "s", ms=3.2, mfc="white", mec="k", mew=0.7, zorder=5)


def legend(ax, ks, colour_of_k):
    from matplotlib.lines import Line2D
    h = [Line2D([], [], ls="none", marker="o", ms=3, color="0.72", mew=0, label="sweep (brute force)")]
    h += [Line2D([], [], color=colour_of_k(k), lw=1.1, label=f"period {k}T" if k > 1 else "period T") for k in ks]
    h += [Line2D([], [], color="k", lw=0.6, ls="--", label="unstable"),
          Line2D([], [], ls="none", marker="s", ms=3.2, mfc="white", mec="k", label="period doubling")]
    ax.legend(handles=h, loc="upper left", ncol=2, fontsize=7, framealpha=0.9)


def main():
    a = sys.argv[1:]
    if len(a) != 4:
        c.fail("usage: pd_cascade.py PD_CASCADE.h5 SCENE.yaml BUILD_DIR OUTDIR")
    path, scene_file, build, outdir = a
    os.makedirs(outdir, exist_ok=True)
    sys.path.insert(0, os.path.join(build, "python"))
    try:
        import vibro
    except ImportError as e:
        c.fail(f"the vibro Python module is not in {build}/python ({e}): build first")
    b, br, bi, scene = read(path)
    # The continued range: the branch's extreme parameters (its ends are placed on the limits;
    # rounded, as the scene validates Ω inside the range and the placed ends may be off by an ulp).
    lo, hi = round(float(np.min(b["p"])), 12), round(float(np.max(b["p"])), 12)

    # ---- the cascade: one chain of branches, each from the last at a located period doubling
    if not np.all(b["residual"] < 1e-8):
        c.fail("a branch point is not periodic to 1e-8")
    pd = [i for i, k in enumerate(bi["kind_name"]) if k == "period_doubling"]
    others = [f"{bi['kind_name'][i]} at {bi['p'][i]:.10f}" for i in range(len(bi["p"])) if i not in pd]
    if others:
        c.fail(f"bifurcations other than period doublings on the cascade: {others}")
    pd.sort(key=lambda i: bi["p"][i])
    nb = len(br["k"])
    if len(pd) < 3:
        c.fail(f"only {len(pd)} period doublings located: no cascade")
    for j in range(1, nb):
        if br["parent"][j] != j - 1 or br["k"][j] != 2 * br["k"][j - 1]:
            c.fail(f"branch {j} (period {br['k'][j]}) is not the doubling of branch {j - 1}")
    for n_, i in enumerate(pd):
        if bi["branch"][i] != n_ or not bi["smooth"][i]:
            c.fail(f"period doubling {n_ + 1} (Ω = {bi['p'][i]}) not located smoothly on branch {n_}")
        if n_ + 1 < nb:
            first = b["p"][br["first"][n_ + 1]]
            if abs(first - bi["p"][i]) > 1e-12:
                c.fail(f"branch {n_ + 1} does not start at period doubling {n_ + 1}")
    pds = np.array([bi["p"][i] for i in pd])
    d = np.diff(pds)
    ratios = d[:-1] / d[1:]
    omega_inf = pds[-1] + d[-1] / (FEIGENBAUM - 1.0)
    print("period doublings located (continuation):")
    for n_, i in enumerate(pd):
        k = int(br["k"][bi["branch"][i]])
        extra = ""
        if n_ >= 1:
            extra = f"   spacing {d[n_ - 1]:.10f}"
        if n_ >= 2:
            extra += f"   ratio {ratios[n_ - 2]:.4f}"
        print(f"  PD{n_ + 1}: period {k}T -> {2 * k}T at Omega = {pds[n_]:.12f}  "
              f"(test {bi['value'][i]:+.1e}, bracket {abs(bi['p_high'][i] - bi['p_low'][i]):.1e}){extra}")
    print(f"  accumulation (last spacing / (delta - 1) past the last): Omega_inf ~ {omega_inf:.9f}")

    # ---- every branch point's k section states
    t = time.time()
    ox, ov = orbit_states(vibro, scene_file, b, lo, hi, "branch point")
    pd_x, _ = orbit_states(vibro, scene_file, {k: bi[k] for k in ("p", "t0", "x", "v", "k")}, lo, hi, "bifurcation")
    allx = np.vstack([o for o in ox])
    allv = np.vstack([o for o in ov])
    xs = float(np.ptp(allx[:, COORD]))
    xs_all = np.ptp(allx, axis=0)
    vs_all = np.ptp(allv, axis=0)
    print(f"orbits' section states: {sum(len(o) for o in ox)} from {len(ox)} branch points ({time.time() - t:.1f} s)")

    # ---- the brute-force sweep, up in Ω from the period-1 orbit at the lower end
    stable_pts = [i for i in range(len(b["p"])) if b["stable"][i] and not b["located"][i]]
    grid = np.concatenate([np.arange(lo, hi + 0.5 * COARSE, COARSE)]
                          + [np.arange(f0, f1 + 0.5 * df, df) for f0, f1, df in FINE] + [b["p"][stable_pts]])
    grid = np.unique(np.round(np.clip(grid, lo, hi), 13))
    i0 = int(np.argmin(b["p"]))   # the branch's end on the lower limit: a period-1 orbit
    if b["k"][i0] != 1 or not b["stable"][i0]:
        c.fail(f"the branch's lower end (Ω = {b['p'][i0]}) is not a stable period-1 orbit")
    s = start_scene(vibro, scene_file, grid[0], b["t0"][i0], b["x"][i0], b["v"][i0])
    t = time.time()
    r = vibro.sweep(s, {"forcing.frequency": grid}, follow=True, transient_periods=TRANSIENT, periods=RECORDED,
                    poincare=True, threads=1)
    if np.any(np.asarray(r.sweep.status) != 0):
        c.fail(f"sweep points stopped early: {np.unique(r.sweep.status)}")
    SX, SV = np.asarray(r.poincare.x), np.asarray(r.poincare.v)    # P × (R+1) × n
    print(f"sweep: {len(grid)} points up in Omega, {TRANSIENT} + {RECORDED} periods each ({time.time() - t:.1f} s)")
    kmax = RECORDED // 2
    sweep_k = np.array([least_period(SX[g], SV[g], xs_all, vs_all, MATCH, kmax) for g in range(len(grid))])

    # ---- where a follow sweep settles within its transient: the orbit attracts fast enough
    # (ρ^N ≤ CONVERGED) and the orbit of half its period, which the sweep sat on before the
    # doubling and which repels past it, repels fast enough (R^N ≥ 1/CONVERGED): next to a
    # doubling both are slow (μ → −1), and a follow sweep lags there.
    def radius_on(j, p):
        idx = np.where(b["branch"] == j)[0]
        order = np.argsort(b["p"][idx])
        return float(np.interp(p, b["p"][idx][order], b["spectral_radius"][idx][order]))

    def settles(p, j):   # multipliers are per kT: the transient is N/k of the branch's maps
        k = int(br["k"][j])
        if radius_on(j, p) ** (TRANSIENT / k) > CONVERGED:
            return False
        parent = int(br["parent"][j])
        return parent < 0 or radius_on(parent, p) ** (2 * TRANSIENT / k) >= 1.0 / CONVERGED

    # ---- check 1: stable branch points lie on the sweep
    where = {float(np.round(p, 13)): g for g, p in enumerate(grid)}
    checked, skipped, worst = 0, 0, 0.0
    for i in stable_pts:
        rho = float(b["spectral_radius"][i])
        if not settles(b["p"][i], int(b["branch"][i])):
            skipped += 1
            continue
        g = where[float(np.round(np.clip(b["p"][i], lo, hi), 13))]
        k = int(b["k"][i])
        if sweep_k[g] != k:
            c.fail(f"Omega = {grid[g]:.10f}: the continuation's stable orbit has period {k}T (rho = {rho:.3f}), "
                   f"the sweep's least period is {sweep_k[g] or 'none'}")
        # the sweep's last k states against the orbit's k states, as sets (any cyclic shift)
        zs = np.hstack([SX[g][-k:] / xs_all, SV[g][-k:] / vs_all])
        zo = np.hstack([ox[i] / xs_all, ov[i] / vs_all])
        dist = min(float(np.max(np.abs(np.roll(zs, sh, axis=0) - zo))) for sh in range(k))
        if dist > MATCH:
            c.fail(f"Omega = {grid[g]:.10f}: the sweep's period-{k} states differ from the stable branch's orbit by "
                   f"{dist:.1e} (relative; allowed {MATCH:.0e})")
        worst = max(worst, dist)
        checked += 1
    print(f"check: {checked} stable branch points lie on the sweep (largest difference {worst:.1e} of the "
          f"x and v ranges; {skipped} left out next to a doubling, where the orbit attracts or its parent repels too slowly: rho^(N/k) > {CONVERGED:.0e} or R^(2N/k) < {1 / CONVERGED:.0e}, N = {TRANSIENT})")
    # ---- check 2: the sweep's period where the continuation has a stable branch
    period_checked = 0
    for g, om in enumerate(grid):
        for j in range(nb):
            idx = np.where(b["branch"] == j)[0]
            p = b["p"][idx]
            a_ = np.searchsorted(p, om) - 1
            if a_ < 0 or a_ + 1 >= len(idx):
                continue
            i1, i2 = idx[a_], idx[a_ + 1]
            if not (b["stable"][i1] and b["stable"][i2]):
                continue
            if not (settles(b["p"][i1], j) and settles(b["p"][i2], j)):
                continue
            if sweep_k[g] != b["k"][i1]:
                c.fail(f"Omega = {om:.10f}: the stable branch there has period {b['k'][i1]}T, the sweep's least "
                       f"period is {sweep_k[g] or 'none'}")
            period_checked += 1
    print(f"check: at {period_checked} grid points inside stable stretches the sweep's period is the branch's")
    # ---- the sweep's own view of the doublings (information: by brute force a doubling shows
    # where the least period found changes, blurred by the slow convergence next to it)
    print("the sweep by itself: last grid point below each doubling with the old period, first with the new one")
    for n_, pv_ in enumerate(pds):
        k = int(br["k"][bi["branch"][pd[n_]]])
        below = np.where((grid < pv_) & (sweep_k == k))[0]
        above = np.where((grid > (grid[below[-1]] if len(below) else lo)) & (sweep_k == 2 * k))[0]
        a_txt = f"period {k} last at {grid[below[-1]]:.7f} ({grid[below[-1]] - pv_:+.1e})" if len(below) else f"period {k} never"
        b_txt = f"period {2 * k} first at {grid[above[0]]:.7f} ({grid[above[0]] - pv_:+.1e})" if len(above) else f"period {2 * k} never"
        print(f"  PD{n_ + 1} {pv_:.10f}: {a_txt}, {b_txt}")

    # ---- the figure
    def colour_of_k(k):
        return K_COLOURS[int(round(np.log2(k))) % len(K_COLOURS)]

    from matplotlib.ticker import MaxNLocator
    fig = plt.figure(figsize=(13, 8.4))
    grid_s = fig.add_gridspec(2, 6, height_ratios=[1.2, 1])
    ax_a = fig.add_subplot(grid_s[0, 0:2])
    ax_b = fig.add_subplot(grid_s[0, 2:4])
    ax_z = fig.add_subplot(grid_s[0, 4:6])
    ax_c = fig.add_subplot(grid_s[1, 0:3])
    ax_d = fig.add_subplot(grid_s[1, 3:6])
    for ax, zoom in ((ax_a, None), (ax_b, ZOOMS[0]), (ax_z, ZOOMS[1])):
        if zoom is None:   # the coarse grid only (the extra points at branch points would crowd it)
            on_coarse = np.abs((grid - lo) / COARSE - np.round((grid - lo) / COARSE)) < 1e-6
            gs = np.where(on_coarse)[0]
        else:
            gs = np.where((grid >= zoom[0][0]) & (grid <= zoom[0][1]))[0]
        ax.scatter(np.repeat(grid[gs], SX.shape[1]), SX[gs][:, :, COORD].ravel(), s=5.0 if zoom is None else 2.5,
                   color="0.7", marker="o", linewidths=0, rasterized=True, zorder=1)
        draw_branches(ax, b, ox, bi, pd_x, colour_of_k, xlim=zoom[0] if zoom else None)
        if zoom:
            ax.set_xlim(*zoom[0])
            ax.set_ylim(*zoom[1])
        ax.set(xlabel="Ω", ylabel=f"{c.mass_label(COORD)} at the section (Ωt = 0 mod 2π)")
        ax.ticklabel_format(axis="x", useOffset=False)
        ax.xaxis.set_major_locator(MaxNLocator(4))
    ax_a.set_xlim(lo, hi)
    y0, y1 = ax_a.get_ylim()
    ax_a.set_ylim(y0, y1 + 0.45 * (y1 - y0))   # room for the legend
    for zoom, tag in zip(ZOOMS, ("b", "c")):
        (x0, x1), (y0, y1) = zoom
        ax_a.add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="0.3", lw=0.6, zorder=6))
        ax_a.annotate(f"({tag})", (x0, y1), xytext=(-14, 2), textcoords="offset points", fontsize=7)
    ax_a.set_title("(a) branches in Ω; grey: the sweep up in Ω", loc="left")
    ax_b.set_title(f"(b) zoom: periods 4T to 64T", loc="left")
    ax_z.set_title(f"(c) zoom: periods 8T to 64T, chaos beyond Ω∞", loc="left")
    legend(ax_a, [int(k) for k in br["k"]], colour_of_k)

    # (d) the real multiplier of largest modulus along each branch vs Ω∞ − Ω
    for j in range(nb):
        idx = np.where(b["branch"] == j)[0]
        mr, mi = b["multipliers_real"][idx], b["multipliers_imag"][idx]
        mu = np.array([row_r[np.argmax(np.where(np.abs(row_i) < 1e-12, np.abs(row_r), -1.0))]
                       for row_r, row_i in zip(mr, mi)])
        dist = omega_inf - b["p"][idx]
        keep = dist > 0
        ax_c.plot(dist[keep], mu[keep], "-", color=colour_of_k(int(br["k"][j])), lw=1.0,
                  label=f"{br['k'][j]}T")
    for pv_ in pds:
        ax_c.plot([omega_inf - pv_], [-1.0], "s", ms=3.5, mfc="white", mec="k")
    ax_c.axhline(-1.0, color="grey", lw=0.6, ls=":")
    ax_c.axhline(1.0, color="grey", lw=0.6, ls=":")
    ax_c.set(xscale="log", ylim=(-3.0, 1.3), xlabel="Ω∞ − Ω", ylabel="real multiplier of largest |μ|")
    ax_c.invert_xaxis()
    ax_c.set_title(f"(d) each branch's multiplier: +1 at its birth, −1 at its doubling (Ω∞ ≈ {omega_inf:.7f})", loc="left")
    ax_c.legend(loc="lower left", ncol=4, fontsize=7)

    # (e) spacings and ratios
    n_idx = np.arange(1, len(d) + 1)
    ax_d.semilogy(n_idx, d, "o-", color="k", ms=4)
    for q in range(len(ratios)):
        ax_d.annotate(f"{ratios[q]:.3f}", ((n_idx[q] + n_idx[q + 1]) / 2, np.sqrt(d[q] * d[q + 1])),
                      textcoords="offset points", xytext=(4, 4), fontsize=7)
    ref = d[-1] * FEIGENBAUM ** (n_idx[-1] - n_idx)
    ax_d.semilogy(n_idx, ref, ":", color="grey", lw=0.8, label=f"slope of δ = {FEIGENBAUM:.4f}")
    ax_d.set(xlabel="n", ylabel="Ω(PD$_{n+1}$) − Ω(PD$_n$)")
    ax_d.set_title("(e) spacing of successive doublings, ratios Δ$_n$/Δ$_{n+1}$ written beside", loc="left")
    ax_d.legend(loc="upper right")
    fig.tight_layout()
    print(f"figure: {c.save(fig, outdir, 'pd_cascade')}")


if __name__ == "__main__":
    main()

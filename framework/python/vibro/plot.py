"""vibro.plot — the standard figures of a study, drawn from a result.

Each function takes a Result (from a run function, or ``vibro.read(path)``) or the path of a result
file, draws on ``ax`` (a new figure's axes when None) and returns the axes, so figures compose and
a script saves them as it likes. matplotlib is imported on first use (``import vibro`` does not
need it). What each draws is read from the groups of docs/results.md; a result without the group
a function needs is refused with a ValueError naming the group and what the result has.

    import vibro, vibro.plot
    r = vibro.continuation("experiments/wagg2004/continuation.yaml")
    ax = vibro.plot.branch(r, coordinate=0)              # x_0 at the fixed phase against Ω
    ax.figure.savefig("branch.png")

Functions: branch (continuation: stable solid, unstable dashed, bifurcations marked by kind),
diagram (brute-force diagram: up and down sweeps overlaid), plane (two-parameter curves),
basin (label image), impact_map (forcing phase against approach speed), section (the crossings of a
hyperplane: forcing phase, or a coordinate, against a coordinate), lyapunov (the spectrum against
the parameter, or as bars at one value).
"""

import numpy as np

__all__ = ["branch", "diagram", "plane", "basin", "impact_map", "section", "lyapunov", "KIND_MARKERS"]

# One marker per bifurcation kind (docs/results.md, /bifurcations kind names).
KIND_MARKERS = {
    "fold": ("o", "tab:red"),
    "period_doubling": ("s", "tab:purple"),
    "neimark_sacker": ("D", "tab:green"),
    "grazing": ("v", "tab:orange"),
    "rising": ("^", "tab:blue"),
    "phase_change": ("x", "0.3"),
    "chatter_change": ("+", "0.3"),
    "other": (".", "0.5"),
    "branch_point": ("P", "tab:brown"),
}


def _result(result):
    if isinstance(result, (str, bytes)) or hasattr(result, "__fspath__"):
        from . import read
        return read(str(result))
    return result


def _need(result, group, what):
    if group not in result:
        raise ValueError(f"vibro.plot.{what}: the result has no /{group} (it has: {', '.join(result.groups)}); "
                         f"it needs a {what} run's result")
    return result[group]


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt
        _, ax = plt.subplots(figsize=(6.4, 4.0))
    return ax


def _names(group, dataset):
    names = group.labels(dataset).get("names", [])
    return [n.decode() if isinstance(n, bytes) else str(n) for n in names]


def branch(result, coordinate=0, *, velocity=False, ax=None, markers=True, palette=None):
    """A continuation's branches: x_coordinate (or v with velocity=True) at the fixed phase
    (/branch x_fixed, continuous along a branch) against the parameter; stable stretches solid,
    unstable dashed, one colour per period (matplotlib's cycle C0, C1, …, or the colours of
    `palette` in turn, e.g. to keep clear of a diagram drawn on the same axes in C0 and C1);
    the located bifurcations marked by kind at their
    parameter on their branch (the branch's value there by linear interpolation between its
    neighbouring points: a located point is not always a point of /branch)."""
    r = _result(result)
    g = _need(r, "branch", "continuation")
    ax = _axes(ax)
    p, ids, stable = g.p, g.branch, g.stable
    y = (g.v_fixed if velocity else g.x_fixed)[:, coordinate]
    ok = g.fixed_ok.astype(bool)
    periods = sorted(set(int(k) for k in g.k))
    labelled = set()
    for b in np.unique(ids):
        rows = np.nonzero((ids == b) & ok)[0]
        if rows.size == 0:
            continue
        k = int(g.k[rows[0]])
        i = periods.index(k)  # one colour per period: many branches stay readable
        colour = palette[i % len(palette)] if palette else f"C{i % 10}"
        # Split at stability changes; each stretch drawn with its style and joined to the next.
        start = 0
        for i in range(1, rows.size + 1):
            if i == rows.size or stable[rows[i]] != stable[rows[start]]:
                seg = rows[start:min(i + 1, rows.size)]
                style = "-" if stable[rows[start]] else "--"
                key = (k, style)
                ax.plot(p[seg], y[seg], style, color=colour, lw=1.0,
                        label=f"period {k}T, {'stable' if style == '-' else 'unstable'}" if key not in labelled else None)
                labelled.add(key)
                start = i
    if markers and "bifurcations" in r:
        f = r["bifurcations"]
        names = _names(f, "kind")
        shown = set()
        for j in range(f.p.size):
            kind = names[int(f.kind[j])] if int(f.kind[j]) < len(names) else "other"
            at = _on_branch(p, ids, ok, g.x, y, int(f.branch[j]), float(f.p[j]), f.x[j])
            if at is None:
                continue
            m, c = KIND_MARKERS.get(kind, KIND_MARKERS["other"])
            ax.plot([f.p[j]], [at], m, color=c, ms=5, mfc="none" if m not in "x+" else c,
                    label=kind if kind not in shown else None, zorder=3)
            shown.add(kind)
    ax.set_xlabel(g.attrs.get("parameter", "p"))
    phase = g.attrs.get("fixed_phase", "0")
    ax.set_ylabel(f"${'v' if velocity else 'x'}_{{{coordinate}}}$ at $\\Omega t \\equiv {phase}$")
    ax.legend(fontsize=7, loc="best")
    return ax


def _on_branch(p, ids, ok, x, y, branch, q, xq):
    """The drawn value at parameter q on `branch`: linear between the two consecutive points whose
    p brackets q; where the branch passes q more than once (past a fold), the crossing whose
    section state is nearest the bifurcation's own (xq). None if the branch does not reach q."""
    rows = np.nonzero((ids == branch) & ok)[0]
    best, distance = None, np.inf
    for a, b in zip(rows[:-1], rows[1:]):
        lo, hi = min(p[a], p[b]), max(p[a], p[b])
        if not (lo <= q <= hi):
            continue
        w = 0.0 if p[b] == p[a] else (q - p[a]) / (p[b] - p[a])
        d = np.max(np.abs((1 - w) * x[a] + w * x[b] - xq))
        if d < distance:
            best, distance = (1 - w) * y[a] + w * y[b], d
    return best


def diagram(result, mass=0, *, ax=None):
    """A brute-force diagram: the recorded stroboscopic x_mass(t0 + nT) of every value reached,
    up sweep (blue) and down sweep (orange, smaller) overlaid: hysteresis shows as points of one
    colour only."""
    r = _result(result)
    g = _need(r, "diagram", "diagram")
    ax = _axes(ax)
    p = g.parameter
    style = {"up": ("tab:blue", 2.0), "down": ("tab:orange", 0.7)}
    for d in str(g.attrs.get("directions", "up down")).split():
        x, reached = g[f"x_{d}"], g[f"reached_{d}"].astype(bool)
        P = x.shape[1]
        colour, size = style[d]
        ax.plot(np.repeat(p[reached], P), x[reached, :, mass].ravel(), ".", ms=size, color=colour,
                label=f"sweep {d}", rasterized=True)
    ax.set_xlabel(g.attrs.get("parameter", "p"))
    ax.set_ylabel(f"$x_{{{mass}}}(t_0 + nT)$")
    ax.legend(fontsize=7, markerscale=4, loc="best")
    return ax


def plane(result, *, ax=None):
    """Two-parameter curves (/curve): each followed bifurcation as a line in (p1, p2), coloured and
    marked by kind; the codimension-two points met on them (/codim2) as black stars."""
    r = _result(result)
    g = _need(r, "curve", "continuation (with run.continue.curve)")
    ax = _axes(ax)
    names = _names(g, "kind")
    shown = set()
    for c in np.unique(g.curve):
        rows = np.nonzero(g.curve == c)[0]
        kind = names[int(g.kind[rows[0]])] if int(g.kind[rows[0]]) < len(names) else "other"
        m, colour = KIND_MARKERS.get(kind, KIND_MARKERS["other"])
        ax.plot(g.p1[rows], g.p2[rows], "-", color=colour, lw=1.0, marker=m, ms=2.5,
                label=kind if kind not in shown else None)
        shown.add(kind)
    if "codim2" in r and r["codim2"].p1.size:  # codimension-two points met on the curves
        c2 = r["codim2"]
        ax.plot(c2.p1, c2.p2, "*", color="black", ms=7, label="codimension two")
    ax.set_xlabel(g.attrs.get("p1", "p1"))
    ax.set_ylabel(g.attrs.get("p2", "p2"))
    ax.legend(fontsize=7, loc="best")
    return ax


def basin(result, *, ax=None, legend=True):
    """A basin run's label image over its two varied values (rows /basin/p1, columns p2), each cell
    centred on its start: one colour per attractor (the legend gives its period and share of the
    grid), grey for not converged within the period budget, black for runs stopped early, white
    for starts not run (interrupted) or outside a stop. Where both values are components of the
    initial state (initial.x[i], initial.v[i]) the attractors' stroboscopic points are marked,
    projected onto the plane."""
    import re
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch
    r = _result(result)
    g = _need(r, "basin", "basin")
    ax = _axes(ax)
    label, p1, p2 = g.label, g.p1, g.p2
    a = r["attractors"] if "attractors" in r else None
    period = a.period if a is not None else np.zeros(0, int)
    n = len(period)
    codes = {-4: ("white", "outside a stop (not run)"), -3: ("white", "not run (interrupted)"),
             -2: ("black", "stopped early"), -1: ("0.75", "not converged")}
    colours = [codes[c][0] for c in (-4, -3, -2, -1)] + [f"C{k % 10}" for k in range(n)]
    dx = (p2[-1] - p2[0]) / max(len(p2) - 1, 1) / 2
    dy = (p1[-1] - p1[0]) / max(len(p1) - 1, 1) / 2
    ax.imshow(label + 4, origin="lower", cmap=ListedColormap(colours), vmin=-0.5, vmax=len(colours) - 0.5,
              extent=[p2[0] - dx, p2[-1] + dx, p1[0] - dy, p1[-1] + dy], aspect="auto", interpolation="nearest")

    def component(path, x, v):
        m = re.fullmatch(r"initial\.([xv])\[(\d+)\]", path)
        return None if not m else (x if m.group(1) == "x" else v)[:, int(m.group(2))]

    handles, total = [], label.size
    path1, path2 = g.attrs.get("p1", "p1"), g.attrs.get("p2", "p2")
    for k in range(n):
        share = 100.0 * np.count_nonzero(label == k) / total
        handles.append(Patch(color=colours[k + 4], label=f"attractor {k}: period {int(period[k])} ({share:.1f} %)"))
        rows = slice(int(a.first[k]), int(a.first[k]) + int(period[k]))
        c1, c2 = component(path1, a.x[rows], a.v[rows]), component(path2, a.x[rows], a.v[rows])
        if c1 is not None and c2 is not None:
            ax.plot(c2, c1, "o", ms=5, mfc=colours[k + 4], mec="black", mew=0.8)
    for code in (-1, -2, -3, -4):
        count = np.count_nonzero(label == code)
        if count:
            handles.append(Patch(facecolor=codes[code][0], edgecolor="0.5",
                                 label=f"{codes[code][1]} ({100.0 * count / total:.1f} %)"))
    if legend:
        ax.legend(handles=handles, loc="upper right", framealpha=0.9, fontsize=7)
    ax.set_xlabel(path2)
    ax.set_ylabel(path1)
    return ax


def impact_map(result, stop=0, *, ax=None):
    """The impact map of one stop (/impact_map): for a simulation, the forcing phase Ωt mod 2π
    against the approach speed before each impact (a period-k orbit with one impact per period
    shows k points); for a sweep, a diagram or a continuation, the approach speed of every impact of every point
    against the swept value (the first sweep parameter; a diagram's up and down sweeps overlaid; a
    continuation's branch points, each orbit over its period):
    the bifurcation diagram of impact velocity."""
    r = _result(result)
    g = _need(r, "impact_map", "simulation, sweep, diagram or continuation (with record.impact_map)")
    ax = _axes(ax)
    on = g.stop == stop
    colour = f"C{stop % 10}"
    if "sweep" in r:
        values = r["sweep"].values[:, 0]
        ax.plot(values[g.point[on]], g.velocity[on], ".", ms=1.5, color=colour, rasterized=True)
        ax.set_xlabel(str(r["sweep"].attrs["parameters"][0]))
    elif "branch" in r:  # each branch point's orbit over kT
        p = r["branch"].p
        ax.plot(p[g.point[on]], g.velocity[on], ".", ms=1.5, color=colour, rasterized=True)
        ax.set_xlabel(str(r["branch"].attrs["parameter"]))
    elif "diagram" in r:  # every value's recorded periods, up and down
        values = r["diagram"].parameter
        for d, (c, size) in enumerate((("tab:blue", 2.0), ("tab:orange", 0.7))):
            rows = on & (g.direction == d)
            if rows.any():
                ax.plot(values[g.point[rows]], g.velocity[rows], ".", ms=size, color=c, rasterized=True,
                        label=("up", "down")[d])
        ax.legend(fontsize=7, markerscale=4, loc="best")
        ax.set_xlabel(str(r["diagram"].attrs["parameter"]))
    else:
        ax.plot(g.phase[on], g.velocity[on], ".", ms=3, color=colour, rasterized=True)
        ax.set_xlim(0.0, 2.0 * np.pi)
        ax.set_xlabel("forcing phase $\\Omega t$ mod $2\\pi$")
    ax.set_ylabel("approach speed at impact")
    stops = g.labels("stop").get("stops", [])
    name = stops[stop] if stop < len(stops) and stops[stop] else f"stop {stop}"
    ax.set_title(f"{name.decode() if isinstance(name, bytes) else name}: {int(np.count_nonzero(on))} impacts", fontsize=8)
    return ax


def section(result, coordinate=0, quantity="v", *, against="phase", ax=None):
    """The Poincaré section on a hyperplane (/section, record.section): ``quantity`` ("x" or "v")
    of ``coordinate`` at each crossing. For a simulation, against the forcing phase Ωt mod 2π
    (``against="phase"``) or against x or v of another coordinate (``against=("x", j)``); for a
    sweep or a diagram, against the swept value (a diagram's up and down sweeps overlaid)."""
    r = _result(result)
    g = _need(r, "section", "simulation, sweep or diagram (with record.section)")
    if quantity not in ("x", "v"):
        raise ValueError(f"vibro.plot.section: quantity is 'x' or 'v', not {quantity!r}")
    ax = _axes(ax)
    y = np.asarray(getattr(g, quantity))
    y = y[:, coordinate] if y.ndim == 2 else y
    if "diagram" in r:
        for d, (c, size) in enumerate((("tab:blue", 2.0), ("tab:orange", 0.7))):
            rows = g.sweep == d
            if rows.any():
                ax.plot(g.parameter[rows], y[rows], ".", ms=size, color=c, rasterized=True, label=("up", "down")[d])
        ax.legend(fontsize=7, markerscale=4, loc="best")
        ax.set_xlabel(str(r["diagram"].attrs["parameter"]))
    elif "sweep" in r:
        values = r["sweep"].values[:, 0]
        ax.plot(values[g.point], y, ".", ms=1.5, color="C0", rasterized=True)
        ax.set_xlabel(str(r["sweep"].attrs["parameters"][0]))
    elif against == "phase":
        ax.plot(g.phase, y, ".", ms=3, color="C0", rasterized=True)
        ax.set_xlim(0.0, 2.0 * np.pi)
        ax.set_xlabel("forcing phase $\\Omega t$ mod $2\\pi$")
    else:
        what, j = against
        other = np.asarray(getattr(g, what))
        ax.plot(other[:, j] if other.ndim == 2 else other, y, ".", ms=3, color="C0", rasterized=True)
        ax.set_xlabel(f"${what}_{{{j}}}$ at the crossing")
    ax.set_ylabel(f"${quantity}_{{{coordinate}}}$ at the crossing")
    ax.set_title(f"section: {len(g.t)} crossings", fontsize=8)
    return ax


def lyapunov(result, *, ax=None):
    """Lyapunov exponents λ_1 ≥ … ≥ λ_p (per unit time): against the parameter, one colour per
    index, for a run along a grid (the structural exponents, −∞ where a stop is held, as ▼ on the
    bottom edge); as bars at the scene's values otherwise (structural ones left out). Zero as a
    thin line: a positive λ_1 is chaos."""
    r = _result(result)
    g = _need(r, "lyapunov", "lyapunov")
    ax = _axes(ax)
    e, finite, reached = g.exponents, g.finite == 1, g.reached == 1
    ax.axhline(0.0, color="0.4", lw=0.6)
    if "parameter" in g:
        p = g.parameter
        values = e[finite & reached[:, None]]
        bottom = values.min() - 0.1 * np.ptp(values) if values.size else -1.0
        for i in range(e.shape[1]):
            colour = f"C{i % 10}"
            ax.plot(p, np.where(finite[:, i] & reached, e[:, i], np.nan), "-", marker=".", ms=3, lw=0.8,
                    color=colour, label=f"$\\lambda_{{{i + 1}}}$")
            s = ~finite[:, i] & reached
            if s.any():
                ax.plot(p[s], np.full(s.sum(), bottom), "v", ms=4, color=colour, clip_on=False)
        if (~finite & reached[:, None]).any():
            ax.text(0.01, 0.03, "▼: −∞ (structural: a stop held)", transform=ax.transAxes, fontsize=7)
        ax.set_ylim(bottom=bottom - 0.02 * abs(bottom))
        ax.set_xlabel(g.attrs.get("parameter", "p"))
        ax.legend(loc="upper left", ncol=e.shape[1], fontsize=7)
    else:
        values = e[0][finite[0]]
        ax.bar(np.arange(1, values.size + 1), values, color="tab:blue")
        ax.set_xlabel("exponent index")
    ax.set_ylabel("Lyapunov exponent (per unit time)")
    return ax

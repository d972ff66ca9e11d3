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
basin (label image), impact_map (forcing phase against approach speed), lyapunov (the spectrum
against the parameter, or as bars at one value).
"""

import numpy as np

__all__ = ["branch", "diagram", "plane", "basin", "impact_map", "lyapunov", "KIND_MARKERS"]

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


def branch(result, coordinate=0, *, velocity=False, ax=None, markers=True):
    """A continuation's branches: x_coordinate (or v with velocity=True) at the fixed phase
    (/branch x_fixed, continuous along a branch) against the parameter; stable stretches solid,
    unstable dashed, one colour per branch; the located bifurcations marked by kind at their
    parameter on their branch (the branch's value there by linear interpolation between its
    neighbouring points: a located point is not always a point of /branch)."""
    r = _result(result)
    g = _need(r, "branch", "continuation")
    ax = _axes(ax)
    p, ids, stable = g.p, g.branch, g.stable
    y = (g.v_fixed if velocity else g.x_fixed)[:, coordinate]
    ok = g.fixed_ok.astype(bool)
    colours = [f"C{i % 10}" for i in range(int(ids.max()) + 1 if ids.size else 0)]
    for b in np.unique(ids):
        rows = np.nonzero((ids == b) & ok)[0]
        if rows.size == 0:
            continue
        k = int(g.k[rows[0]])
        # Split at stability changes; each stretch drawn with its style and joined to the next.
        start = 0
        for i in range(1, rows.size + 1):
            if i == rows.size or stable[rows[i]] != stable[rows[start]]:
                seg = rows[start:min(i + 1, rows.size)]
                ax.plot(p[seg], y[seg], "-" if stable[rows[start]] else "--", color=colours[int(b)], lw=1.0,
                        label=f"branch {int(b)} ({k}T)" if start == 0 else None)
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
    marked by kind."""
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
    ax.set_xlabel(g.attrs.get("p1", "p1"))
    ax.set_ylabel(g.attrs.get("p2", "p2"))
    ax.legend(fontsize=7, loc="best")
    return ax


def basin(result, *, ax=None):
    """A basin run's label image: one colour per attractor (its period in the legend), grey for
    not converged, white for stopped early, not run or inadmissible."""
    r = _result(result)
    g = _need(r, "basin", "basin")
    ax = _axes(ax)
    import matplotlib.colors as mcolors
    label = g.label
    n = int(label.max()) + 1 if label.size and label.max() >= 0 else 0
    colours = ["white", "white", "white", "0.6"] + [f"C{i % 10}" for i in range(n)]
    cmap = mcolors.ListedColormap(colours)
    image = np.clip(label, -4, None) + 4  # −4 … n−1 → 0 … n+3
    ax.imshow(image, origin="lower", aspect="auto", interpolation="nearest", cmap=cmap, vmin=-0.5,
              vmax=len(colours) - 0.5, extent=[g.p2[0], g.p2[-1], g.p1[0], g.p1[-1]])
    if "attractors" in r:
        period = r["attractors"].period
        from matplotlib.patches import Patch
        handles = [Patch(color=f"C{i % 10}", label=f"attractor {i} ({int(period[i])}T)") for i in range(n)]
        if np.any(label == -1):
            handles.append(Patch(color="0.6", label="not converged"))
        ax.legend(handles=handles, fontsize=7, loc="best")
    ax.set_xlabel(g.attrs.get("p2", "p2"))
    ax.set_ylabel(g.attrs.get("p1", "p1"))
    return ax


def impact_map(result, stop=0, *, ax=None):
    """A simulation's impact map of one stop (/impact_map): forcing phase Ωt mod 2π against the
    approach speed before each impact."""
    r = _result(result)
    g = _need(r, "impact_map", "simulation (with record.impact_map)")
    ax = _axes(ax)
    rows = g.stop == stop
    ax.plot(g.phase[rows], g.velocity[rows], ".", ms=2, color="tab:blue", rasterized=True)
    ax.set_xlim(0.0, 2.0 * np.pi)
    ax.set_xlabel("forcing phase $\\Omega t$ mod $2\\pi$")
    ax.set_ylabel("approach speed before impact")
    stops = g.labels("stop").get("stops", [])
    name = stops[stop] if stop < len(stops) else f"stop {stop}"
    ax.set_title(f"impact map of {name.decode() if isinstance(name, bytes) else name}: {int(np.count_nonzero(rows))} impacts",
                 fontsize=8)
    return ax


def lyapunov(result, *, ax=None):
    """Lyapunov exponents: against the parameter (one line per exponent) for a run along a grid,
    as bars at the scene's values otherwise; structural exponents (−∞, a stop held) left out."""
    r = _result(result)
    g = _need(r, "lyapunov", "lyapunov")
    ax = _axes(ax)
    exponents, finite, reached = g.exponents, g.finite.astype(bool), g.reached.astype(bool)
    if "parameter" in g:
        p = g.parameter
        for i in range(exponents.shape[1]):
            y = np.where(finite[:, i] & reached, exponents[:, i], np.nan)
            ax.plot(p, y, "-", lw=1.0, label=f"$\\lambda_{{{i + 1}}}$")
        ax.set_xlabel(g.attrs.get("parameter", "p"))
    else:
        values = exponents[0][finite[0]]
        ax.bar(np.arange(1, values.size + 1), values, color="tab:blue")
        ax.set_xlabel("exponent index")
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_ylabel(f"exponent [{g.attrs.get('units', '1/time')}]")
    if "parameter" in g:
        ax.legend(fontsize=7, loc="best", ncol=2)
    return ax

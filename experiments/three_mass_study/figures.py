"""The three-mass study's figure and numbers (README, "A bifurcation study end to end").

    python3 experiments/three_mass_study/figures.py DATA_DIR OUT_DIR

reads the result files run_study.sh writes into DATA_DIR (continuation.h5, plane.h5, diagram.h5,
basin.h5, impact_map.h5) and draws OUT_DIR/three_mass_study.png (and .pdf): (a) the branches of
periodic orbits with branch switching, stable solid and unstable dashed, bifurcations marked;
(b) the brute-force diagram, up and down; (c) the two-parameter plane of the folds, period
doublings and grazings; (d) the basins at Ω = 1.85; (e) and (f) the impact maps of the two stops
at Ω = 1.6. study.py calls draw() with the results it computed in memory. Every panel is drawn by
vibro.plot; the numbers the README quotes are printed.
"""
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tools", "figures"))
from common import vibro_module  # noqa: E402

NAMES = ("continuation", "plane", "diagram", "basin", "impact_map")


def summary(r):
    """The numbers the README quotes, from the results (a dict of vibro.Result by NAMES)."""
    lines = []
    c = r["continuation"]
    names = c.bifurcations.labels("kind")["names"]
    kinds = [names[k] for k in c.bifurcations.kind]
    lines.append(f"continuation: {c.branches.k.size} branches (periods {sorted(set(int(k) for k in c.branches.k))}), "
                 f"{c.branch.p.size} orbits, {c.meta['recognised']} switchings recognised, "
                 f"{kinds.count('period_doubling')} period doublings, {kinds.count('fold')} folds, "
                 f"{kinds.count('grazing')} grazings, {c.meta['wall_time']:.1f} s")
    if r.get("plane") is not None and "curve" in r["plane"]:
        g = r["plane"].curve
        cn = g.labels("kind")["names"]
        counts = {}
        for i in np.unique(g.curve):
            kind = cn[int(g.kind[g.curve == i][0])]
            counts[kind] = counts.get(kind, 0) + 1
        lines.append(f"plane: {len(np.unique(g.curve))} curves ({', '.join(f'{v} {k}' for k, v in sorted(counts.items()))}), "
                     f"{g.p1.size} points, {r['plane'].meta['wall_time']:.1f} s")
    d = r["diagram"]
    lines.append(f"diagram: {d.diagram.parameter.size} values up and down, "
                 f"{d.meta['points_not_periodic']} not periodic, {d.meta['points_not_settled']} not settled, "
                 f"{d.meta['wall_time']:.1f} s")
    b = r["basin"]
    shares = [f"period {int(k)}: {100.0 * c / b.basin.label.size:.1f} %" for k, c in zip(b.attractors.period, b.attractors.cells)]
    lines.append(f"basin at Ω = {2 * np.pi / b.scene.attrs['period']:.4g}: {len(shares)} attractors ({'; '.join(shares)}), "
                 f"{b.meta['wall_time']:.1f} s")
    m = r["impact_map"].impact_map
    lines.append(f"impact map at Ω = {2 * np.pi / r['impact_map'].scene.attrs['period']:.4g}: "
                 f"{int(np.count_nonzero(m.stop == 0))} and {int(np.count_nonzero(m.stop == 1))} impacts on the two stops")
    return lines


def draw(r, outdir):
    """The figure from the results (a dict of vibro.Result by NAMES; 'plane' may be None)."""
    vibro = vibro_module()
    os.makedirs(outdir, exist_ok=True)
    plt.rcParams.update({"font.size": 8, "axes.titlesize": 8, "legend.fontsize": 6})
    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5))
    (a, b, c), (d, e, f) = axes
    vibro.plot.branch(r["continuation"], coordinate=2, ax=a)
    a.set_title("(a) branches of periodic orbits, switched at period doublings")
    vibro.plot.diagram(r["diagram"], mass=2, ax=b)
    b.set_title("(b) brute-force diagram, up and down")
    if r.get("plane") is not None and "curve" in r["plane"]:
        vibro.plot.plane(r["plane"], ax=c)
        c.set_title("(c) folds, period doublings and grazings in two parameters")
    else:
        c.set_axis_off()
    vibro.plot.basin(r["basin"], ax=d)
    d.set_title("(d) basins at $\\Omega$ = 1.85")
    vibro.plot.impact_map(r["impact_map"], stop=0, ax=e)
    e.set_title("(e) impact map, stop below mass 0, $\\Omega$ = 1.6")
    vibro.plot.impact_map(r["impact_map"], stop=1, ax=f)
    f.set_title("(f) impact map, clearance m1–m2, $\\Omega$ = 1.6")
    fig.tight_layout()
    for ext in ("png", "pdf"):
        fig.savefig(os.path.join(outdir, f"three_mass_study.{ext}"), bbox_inches="tight", dpi=130)
    plt.close(fig)
    return os.path.join(outdir, "three_mass_study.png")


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: figures.py DATA_DIR OUT_DIR")
    vibro = vibro_module()
    data, out = sys.argv[1], sys.argv[2]
    r = {}
    for name in NAMES:
        path = os.path.join(data, f"{name}.h5")
        if not os.path.isfile(path):
            if name == "plane":
                r[name] = None
                continue
            sys.exit(f"error: {path}: no such file (run experiments/three_mass_study/run_study.sh)")
        r[name] = vibro.read(path)
        if r[name].status != "completed":
            sys.exit(f"error: {path}: status {r[name].status}: {r[name].message}")
    print(draw(r, out))
    print("\n".join(summary(r)))


if __name__ == "__main__":
    main()

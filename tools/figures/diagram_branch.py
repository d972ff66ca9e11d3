"""A brute-force diagram with a continuation drawn over it, and the checks that tie the two together:
the two-panel figure of the experiments that run both (experiments/shaken, experiments/soft_impact).

    diag = read_diagram("diagram.h5")           # the stroboscopic x_0 of both sweeps, per value
    cont = read_continuation("continuation.h5") # /branch at the fixed phase, /bifurcations
    worst, compared = branch_against_diagram(diag, cont)
    fig, (a, c) = draw(diag_path, cont_path, cont, lower="k")

The diagram records x(t0 + nT) at phase 0; the branch is compared (and drawn) at its fixed phase,
which must then be 0 too (`read_continuation` refuses another). Panel (a) is vibro.plot's diagram
and branch figures on one axes, panel (b) the period (or impacts per period) of both sweeps; every
located bifurcation is a dotted vertical line through both, in vibro.plot's colour for its kind.
"""

import numpy as np

from common import fail, vibro_module

# The branches' colours by period: clear of the sweeps' blue and orange.
BRANCH_COLOURS = ["black", "tab:green", "tab:purple", "tab:brown"]


def read_diagram(path, coordinate=0):
    """/diagram of a result: the parameter W, per sweep ("up", "down") its x_coordinate(t0 + nT)
    (values × recorded periods), least period k (0: none found), impacts per period and reached
    flags, and the run's wall time. Fails unless every value of both sweeps was reached."""
    import h5py
    with h5py.File(path, "r") as f:
        g = f["diagram"]
        sweeps = {s: {"x": g[f"x_{s}"][()][:, :, coordinate], "k": g[f"k_{s}"][()],
                      "impacts": g[f"impacts_{s}"][()], "reached": g[f"reached_{s}"][()]}
                  for s in ("up", "down")}
        wall = float(f["meta"].attrs.get("wall_time", np.nan))
        W = g["parameter"][()]
    for s, sw in sweeps.items():
        if not sw["reached"].all():
            fail(f"{path}: sweep {s}: {np.count_nonzero(sw['reached'] == 0)} diagram values not reached")
    return {"W": W, "sweeps": sweeps, "wall": wall}


def read_continuation(path, coordinate=0):
    """/branch, /branches and /bifurcations of a continuation result: per point its branch, p,
    x_coordinate at the fixed phase, stability, period and whether the fixed-phase state was
    computed; per branch its period; the located bifurcations as (kind, p, branch, smooth); the
    run's wall time. Fails if the fixed phase is not 0 (the diagram's stroboscopic phase)."""
    import h5py
    with h5py.File(path, "r") as f:
        b = f["branch"]
        c = {"branch": b["branch"][()], "p": b["p"][()], "x": b["x_fixed"][()][:, coordinate],
             "stable": b["stable"][()], "k": b["k"][()], "ok": b["fixed_ok"][()],
             "branch_k": f["branches"]["k"][()], "wall": float(f["meta"].attrs.get("wall_time", np.nan))}
        fixed_phase = float(b.attrs.get("fixed_phase", 0.0))
        bif = f["bifurcations"]
        names = [n.decode() if isinstance(n, bytes) else n for n in bif["kind"].attrs["names"]]
        c["marks"] = [(names[int(q)], float(v), int(bb), int(sm))
                      for q, v, bb, sm in zip(bif["kind"][()], bif["p"][()], bif["branch"][()], bif["smooth"][()])]
    if fixed_phase != 0.0:
        fail(f"{path}: the branch's fixed phase is {fixed_phase}, not 0 (the diagram's stroboscopic phase)")
    return c


def branch_against_diagram(diag, cont):
    """The stable period-1 branch points that fall on a diagram value (to 1e-9) against the
    diagram's period-1 points there (the nearer of the two sweeps): (largest |x_branch − x_diagram|,
    number compared)."""
    W, worst, compared = diag["W"], 0.0, 0
    for pi, xi, si, ki, oki in zip(cont["p"], cont["x"], cont["stable"], cont["k"], cont["ok"]):
        i = int(np.argmin(np.abs(W - pi)))
        if si != 1 or ki != 1 or oki != 1 or abs(W[i] - pi) > 1e-9:
            continue
        cands = [sw["x"][i] for sw in diag["sweeps"].values() if sw["k"][i] == 1]
        if cands:
            worst = max(worst, min(np.max(np.abs(c - xi)) for c in cands))
            compared += 1
    return worst, compared


def check_agreement(worst, compared):
    """Prints the comparison and fails if no point was compared or they differ by more than 1e-6,
    the diagram's periodicity tolerance."""
    print(f"  stable period-1 branch points on diagram values: {compared}, max |x_branch − x_diagram| = {worst:.2e}")
    if compared == 0:
        fail("no stable branch point fell on a diagram value")
    if worst > 1e-6:
        fail(f"branch and diagram disagree by {worst:.2e} (> 1e-6, the diagram's periodicity tolerance)")


def draw(diagram_path, continuation_path, cont, lower="k"):
    """The two panels: (a) both sweeps' points with the continued branches (vibro.plot), (b) each
    sweep's least period k (lower="k") or impacts per period (lower="impacts"); the located
    bifurcations as dotted vertical lines through both. Returns the figure and the two axes."""
    import matplotlib.pyplot as plt
    vibro = vibro_module()
    diag = read_diagram(diagram_path)
    fig, (a, c) = plt.subplots(2, 1, figsize=(7, 6.2), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    vibro.plot.diagram(diagram_path, ax=a)
    vibro.plot.branch(continuation_path, ax=a, palette=BRANCH_COLOURS)
    a.set_xlabel("")
    for s, col in (("up", "tab:blue"), ("down", "tab:orange")):
        c.plot(diag["W"], diag["sweeps"][s][lower], "-" if s == "up" else "--", color=col, lw=1, label=s)
    for n, v, _, _ in cont["marks"]:
        colour = vibro.plot.KIND_MARKERS.get(n, vibro.plot.KIND_MARKERS["other"])[1]
        for ax in (a, c):
            ax.axvline(v, color=colour, lw=0.6, ls=":")
    c.set_ylabel("period k\n(0: none ≤ 8)" if lower == "k" else "impacts\nper period")
    c.legend(loc="upper right", fontsize=7)
    return fig, (a, c)


def print_sweeps(diag, symbol, max_period=8):
    """The diagram's summary line and, per sweep, how many values are of period 1, of 2..max_period,
    and not periodic."""
    W = diag["W"]
    print(f"diagram: {len(W)} values of {symbol} in [{W[0]:g}, {W[-1]:g}], up and down, {diag['wall']:.2f} s wall")
    for s, sw in diag["sweeps"].items():
        kk = sw["k"]
        print(f"  sweep {s}: {np.count_nonzero(kk == 1)} period-1, {np.count_nonzero(kk > 1)} of period 2..{max_period}, "
              f"{np.count_nonzero(kk == 0)} not periodic within {max_period} periods")

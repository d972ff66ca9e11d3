"""Wagg (2004), fig. 5: proportion of the forcing period each stop's mass sticks, vs Ω:
(a) over the whole scan, (b) zoomed on the rising. Each stop's total sticking fraction is a line;
the parts of a split sticking phase (from /phases, in order of their phase within the period) are
separate marker series; located transitions (/transitions) are vertical lines labelled with their Ω;
orbits that are not periodic (/scan/periodic == 0) are red crosses.

The paper's caption calls the curve "sticking time of mass 2". The script computes which mass it
is: the stop whose sticking phase drops at the located rising near Ω = 0.256.

    vibro run experiments/wagg2004/rising_scan.yaml -o rising_scan.h5
    vibro run experiments/wagg2004/fig5_zoom.yaml   -o fig5_zoom.h5
    python3 tools/figures/fig5_sticking_time.py rising_scan.h5 fig5_zoom.h5 OUTDIR
"""
import common as c
import matplotlib.pyplot as plt
import numpy as np

RISING_NEAR = 0.256   # the paper's rising (fig. 4: between Ω = 0.255 and 0.2561)


def dropping_stop(loc):
    """The stop whose longest sticking phase changes most across the located rising nearest
    RISING_NEAR, with the numbers that decide it."""
    tr = loc.transitions
    rising = [i for i in range(len(tr["kind"])) if tr["kind_names"][int(tr["kind"][i])] == "rising"]
    if not rising:
        c.fail("no rising transition located in the scan")
    i = min(rising, key=lambda r: abs(tr["parameter"][r] - RISING_NEAR))
    pr = tr["parameter"][i]
    below = np.searchsorted(loc.p, pr) - 1
    above = below + 1
    if below < 0 or above >= len(loc.p):
        c.fail(f"rising at {pr} is not inside the scan grid")
    changes = []
    for j in range(loc.scene.m):
        parts, _ = c.phase_parts(loc, j)
        lo, hi = np.nanmax(parts[below]), np.nanmax(parts[above])
        changes.append((abs(hi - lo), j, lo, hi))
    changes.sort(reverse=True)
    _, j, lo, hi = changes[0]
    return i, pr, j, lo, hi, below, above, int(tr["stop"][i])


def main():
    (full, zoom), outdir = c.args(2, 2, "RISING_SCAN.h5 FIG5_ZOOM.h5 OUTDIR")
    a, b = c.read_locate(full), c.read_locate(zoom)
    i, pr, j, lo, hi, below, above, tr_stop = dropping_stop(a)
    sc = a.scene
    mass = int(sc.stop_mass[j])
    if tr_stop != j:
        c.fail(f"the located rising is on stop {tr_stop}, but stop {j}'s sticking phase changes most")
    # The total drop: from just below the rising to just past the vanishing of the same stop's 2nd part.
    tr = a.transitions
    van = [k for k in range(len(tr["kind"])) if tr["kind_names"][int(tr["kind"][k])] == "vanishing"
           and int(tr["stop"][k]) == j and tr["parameter"][k] > pr]
    after = np.searchsorted(a.p, tr["parameter"][min(van, key=lambda k: tr["parameter"][k])]) if van else above

    fig, axes = plt.subplots(1, 2, figsize=(11, 5.0))
    keys = []
    for ax, loc, tag in ((axes[0], a, "(a)"), (axes[1], b, "(b)")):
        c.draw_sticking_vs_parameter(ax, loc, show_transitions=False)
        ax.relim()
        ax.set_ylim(0, 1.15 * np.nanmax(loc.sticking))
        keys.append(c.draw_transitions(ax, loc))
        npp = int(np.sum(loc.periodic == 0))
        ax.set_title(f"{tag} {loc.p.min():g} ≤ $\\Omega$ ≤ {loc.p.max():g}, {len(loc.p)} orbits"
                     + (f", {npp} NOT periodic" if npp else ", all periodic"), loc="left")
    axes[1].legend(loc="center right", fontsize=7, framealpha=0.9)
    fig.suptitle(f"Wagg (2004) fig. 5: proportion of sticking time. The sticking time that drops at the rising is "
                 f"that of the paper's mass {mass + 1} (our mass {mass}, stop {sc.stop_name[j]}); "
                 f"the paper's caption says mass 2", fontsize=9)
    fig.tight_layout(rect=(0, 0.13, 1, 1))
    for ax, key in zip(axes, keys):     # the located transitions, numbered as on the plots
        if key:
            box = ax.get_position()
            fig.text(box.x0, 0.11, "located transitions:\n" + "\n".join(key), va="top", fontsize=7)
    out = c.save(fig, outdir, "fig5_sticking_time")
    names = tr["kind_names"]
    print(f"fig5: rising at Ω = {pr:.10f} on stop {sc.stop_name[j]} = paper's mass {mass + 1} (our mass {mass}): "
          f"its longest sticking phase {lo:.5f} T at Ω = {a.p[below]:g} -> {hi:.5f} T at {a.p[above]:g}; total "
          f"sticking {a.sticking[below, j]:.5f} T -> {a.sticking[after, j]:.5f} T at Ω = {a.p[after]:g}")
    for loc, tag in ((a, "(a)"), (b, "(b)")):
        t = loc.transitions
        print(f"  {tag} {len(loc.p)} orbits, {int(np.sum(loc.periodic == 0))} not periodic; transitions: "
              + "; ".join(f"{names[int(t['kind'][k])]} {sc.stop_name[int(t['stop'][k])] if t['stop'][k] >= 0 else '-'}"
                          f" {t['parameter'][k]:.10f}" for k in range(len(t["kind"]))))
    print(f"  wrote {out}")


if __name__ == "__main__":
    main()

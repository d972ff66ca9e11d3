"""Sticking time of every stop vs the located parameter, for any `run.kind: locate` file (e.g. a
3-mass chain): like fig5_sticking_time.py, one line per stop (total sticking fraction of T), the
parts of split sticking phases as separate markers (in order of their phase within the period),
located transitions as labelled vertical lines, and non-periodic orbits as red crosses.

    vibro run SCENE_LOCATE.yaml -o scan.h5
    python3 tools/figures/three_mass_rising.py scan.h5 OUTDIR     # OUTDIR/three_mass_rising.{png,pdf}
"""
import common as c
import matplotlib.pyplot as plt
import numpy as np


def main():
    (path,), outdir = c.args(1, 1, "LOCATE.h5 OUTDIR")
    loc = c.read_locate(path)
    sc = loc.scene
    fig, ax = plt.subplots(figsize=(9, 4.6))
    c.draw_sticking_vs_parameter(ax, loc, show_transitions=False)
    top = np.nanmax(loc.sticking) if np.any(np.isfinite(loc.sticking)) else 1.0
    ax.set_ylim(0, 1.15 * max(top, 1e-3))
    key = c.draw_transitions(ax, loc)
    if key:
        ax.text(1.01, 0.0, "located transitions:\n" + "\n".join(key), transform=ax.transAxes, fontsize=7,
                va="bottom")
    tr = loc.transitions
    npp = int(np.sum(loc.periodic == 0))
    ax.set_title(f"{sc.name}: sticking time per stop, {len(loc.p)} orbits"
                 + (f", {npp} NOT periodic" if npp else ", all periodic") + f"; {sc.n} masses, {sc.m} stops")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    fig.tight_layout()
    out = c.save(fig, outdir, "three_mass_rising")
    names = tr["kind_names"]
    print(f"{path}: {len(loc.p)} orbits over {loc.p.min():g} .. {loc.p.max():g} ({loc.parameter_path}), "
          f"{npp} not periodic, periods k = {sorted(set(int(k) for k in loc.k))}; transitions: "
          + ("; ".join(f"{names[int(tr['kind'][k])]} {sc.stop_name[int(tr['stop'][k])] if tr['stop'][k] >= 0 else '-'}"
                       f" {tr['parameter'][k]:.10f}" for k in range(len(tr["kind"]))) or "none"))
    for j in range(sc.m):
        d = np.diff(loc.sticking[:, j])
        if len(d) == 0:
            continue
        q = int(np.nanargmin(d))
        print(f"  {sc.stop_label(j).replace('$', '')}: sticking {np.nanmin(loc.sticking[:, j]):.5f} .. {np.nanmax(loc.sticking[:, j]):.5f} T; "
              f"largest drop {-d[q]:.5f} T between {loc.p[q]:g} and {loc.p[q + 1]:g}")
    print(f"  wrote {out}")


if __name__ == "__main__":
    main()

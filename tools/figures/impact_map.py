"""The impact map (record.impact_map; layout of /impact_map in docs/results.md).

    python3 tools/figures/impact_map.py IN.h5 OUTDIR

A simulation: one panel per stop with impacts, forcing phase Ωt mod 2π against the approach
speed at impact (the section papers in the field plot; a period-k orbit with one impact per
period shows k points). A sweep: one panel per stop, the approach speed of every impact of every
point against the swept value (the first sweep parameter) — the bifurcation diagram of impact
velocity; a diagram run's (record.impact_map) the same, its up and down sweeps overlaid.

Checks (the script fails if one does not hold): every approach speed is positive, every phase is
in [0, 2π), every stop index names a stop of /scene, and a sweep's rows add up to its points'.

Drawn by vibro.plot.impact_map. Writes OUTDIR/impact_map.png and OUTDIR/impact_map.pdf.
"""

import math

import numpy as np

from common import args, fail, plt, save, vibro_module

vibro = vibro_module()


def main():
    (path,), outdir = args(1, 1, "IN.h5 OUTDIR")
    r = vibro.read(path)
    if "impact_map" not in r:
        fail(f"{path}: no /impact_map (record it with record.impact_map: true)")
    m = r.impact_map
    stop, phase, speed = m.stop, m.phase, m.velocity
    names = [str(s) for s in m.labels("stop").get("stops", [])]
    if "sweep" in r and int(np.sum(m.rows)) != len(m.t):
        fail(f"/impact_map: rows add up to {int(np.sum(m.rows))}, {len(m.t)} impacts stored")
    if len(m.t) == 0:
        fail(f"{path}: no impacts recorded")
    if not (speed > 0).all():
        fail("/impact_map/velocity: an approach speed is not positive")
    if not ((phase >= 0) & (phase < 2 * math.pi)).all():
        fail("/impact_map/phase: a phase outside [0, 2π)")
    if not ((stop >= 0) & (stop < max(len(names), stop.max() + 1))).all():
        fail("/impact_map/stop: an index names no stop")

    stops = sorted(set(stop.tolist()))
    fig, axes = plt.subplots(1, len(stops), figsize=(3.4 * len(stops), 3.0), squeeze=False)
    for ax, j in zip(axes[0], stops):
        vibro.plot.impact_map(r, stop=j, ax=ax)
    fig.tight_layout()
    print(save(fig, outdir, "impact_map"))


if __name__ == "__main__":
    main()

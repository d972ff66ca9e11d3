"""The impact map (record.impact_map; layout of /impact_map in docs/results.md).

    python3 tools/figures/impact_map.py IN.h5 OUTDIR

A simulation: one panel per stop with impacts, forcing phase Ωt mod 2π against the approach
speed at impact (the section papers in the field plot; a period-k orbit with one impact per
period shows k points). A sweep: one panel per stop, the approach speed of every impact of every
point against the swept value (the first sweep parameter) — the bifurcation diagram of impact
velocity.

Checks (the script fails if one does not hold): every approach speed is positive, every phase is
in [0, 2π), every stop index names a stop of /scene, and a sweep's rows add up to its points'.

Writes OUTDIR/impact_map.png and OUTDIR/impact_map.pdf.
"""

import math

import numpy as np

from common import args, fail, plt, save, STOP_COLOURS
import h5py


def main():
    (path,), outdir = args(1, 1, "IN.h5 OUTDIR")
    with h5py.File(path, "r") as f:
        if "impact_map" not in f:
            fail(f"{path}: no /impact_map (record it with record.impact_map: true)")
        m = f["impact_map"]
        t, stop, phase, speed = (m[name][()] for name in ("t", "stop", "phase", "velocity"))
        names = [str(s) for s in m["stop"].attrs.get("stops", [])]
        sweep = "sweep" in f
        if sweep:
            point = m["point"][()]
            rows = m["rows"][()]
            values = f["sweep/values"][()][:, 0]
            label = str(f["sweep"].attrs["parameters"][0])
            if rows.sum() != len(t):
                fail(f"/impact_map: rows add up to {rows.sum()}, {len(t)} impacts stored")
    if len(t) == 0:
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
        on = stop == j
        colour = STOP_COLOURS[j % len(STOP_COLOURS)]
        title = names[j] if j < len(names) and names[j] else f"stop {j}"
        if sweep:
            ax.plot(values[point[on]], speed[on], ".", ms=1.5, color=colour)
            ax.set_xlabel(label)
        else:
            ax.plot(phase[on], speed[on], ".", ms=3, color=colour)
            ax.set_xlim(0, 2 * math.pi)
            ax.set_xlabel("forcing phase Ωt mod 2π")
        ax.set_title(f"{title}: {on.sum()} impacts")
    axes[0][0].set_ylabel("approach speed at impact")
    fig.tight_layout()
    print(save(fig, outdir, "impact_map"))


if __name__ == "__main__":
    main()

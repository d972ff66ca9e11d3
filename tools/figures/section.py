"""The Poincaré section on a hyperplane (record.section; layout of /section in docs/results.md).

    python3 tools/figures/section.py [--coordinate=J] IN.h5 OUTDIR

A simulation: the velocity of coordinate J (default 0) at each crossing against the forcing phase
Ωt mod 2π, beside it against the position of another coordinate (0, or 1 for J = 0). A sweep or a diagram: the velocity at every
crossing of every point against the swept value (a diagram's up and down sweeps overlaid).

Checks (the script fails if one does not hold): every phase is in [0, 2π), every direction is
±1, the crossings of one run alternate in direction when both are recorded, and a sweep's rows
add up to its points'.

Drawn by vibro.plot.section. Writes OUTDIR/section.png and OUTDIR/section.pdf.
"""

import math
import sys

import numpy as np

from common import args, fail, plt, save, vibro_module

vibro = vibro_module()


def main():
    coordinate = 0
    for a in list(sys.argv[1:]):
        if a.startswith("--coordinate="):
            coordinate = int(a.split("=", 1)[1])
            sys.argv.remove(a)
    (path,), outdir = args(1, 1, "[--coordinate=J] IN.h5 OUTDIR")
    r = vibro.read(path)
    if "section" not in r:
        fail(f"{path}: no /section (record it with record.section)")
    s = r.section
    if len(s.t) == 0:
        fail(f"{path}: no crossings recorded")
    if "sweep" in r and int(np.sum(s.rows)) != len(s.t):
        fail(f"/section: rows add up to {int(np.sum(s.rows))}, {len(s.t)} crossings stored")
    if not ((s.phase >= 0) & (s.phase < 2 * math.pi)).all():
        fail("/section/phase: a phase outside [0, 2π)")
    if not np.isin(s.direction, (-1, 1)).all():
        fail("/section/direction: a direction other than ±1")
    if "sweep" not in r and "diagram" not in r and (s.direction == 1).any() and (s.direction == -1).any():
        if (np.diff(s.direction) == 0).any():
            fail("/section/direction: two crossings in a row in the same direction")
    if not 0 <= coordinate < s.x.shape[1]:
        fail(f"coordinate {coordinate}: the system has {s.x.shape[1]} coordinates")

    if "sweep" in r or "diagram" in r:
        fig, ax = plt.subplots(figsize=(4.4, 3.2))
        vibro.plot.section(r, coordinate, "v", ax=ax)
    else:
        fig, axes = plt.subplots(1, 2, figsize=(7.6, 3.2), squeeze=False)
        vibro.plot.section(r, coordinate, "v", ax=axes[0][0])
        other = 0 if coordinate != 0 else min(1, s.x.shape[1] - 1)  # another coordinate, where there is one
        vibro.plot.section(r, coordinate, "v", against=("x", other), ax=axes[0][1])
    fig.tight_layout()
    print(save(fig, outdir, "section"))


if __name__ == "__main__":
    main()

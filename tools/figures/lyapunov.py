"""Lyapunov spectrum along a parameter (run.kind: lyapunov with a grid; /lyapunov in docs/results.md).

    python3 tools/figures/lyapunov.py IN.h5 OUTDIR

Every exponent λ_1 ≥ … ≥ λ_p (per unit time) against the parameter, one colour per index; the
structural exponents (stops held: −∞ exactly, stored as `finite` = 0) are drawn as ▼ on the
bottom edge, and zero as a thin line: a positive λ_1 is chaos.

Checks (the script fails if one does not hold): every point was reached; where the full spectrum
is finite its sum is negative (a damped system with r < 1 contracts phase volume). The order
within a complex pair is not checked: its two QR averages agree only to their finite-time noise.

Drawn by vibro.plot.lyapunov. Writes OUTDIR/lyapunov.png and OUTDIR/lyapunov.pdf.
"""

import numpy as np

from common import args, fail, plt, save, vibro_module

vibro = vibro_module()


def main():
    (path,), outdir = args(1, 1, "IN.h5 OUTDIR")
    r = vibro.read(path)
    if "lyapunov" not in r or "parameter" not in r.lyapunov:
        fail(f"{path}: no /lyapunov/parameter (not a run.kind: lyapunov file along a parameter)")
    g = r.lyapunov
    p, e, finite, reached = g.parameter, g.exponents, g.finite, g.reached
    if not reached.all():
        fail(f"{np.count_nonzero(reached == 0)} points not reached")
    for i in range(len(p)):
        if finite[i].all() and not e[i].sum() < 0.0:
            fail(f"point {i}: the spectrum {e[i]} does not sum to < 0")
    fig, ax = plt.subplots(figsize=(7, 4))
    vibro.plot.lyapunov(r, ax=ax)
    name, title = g.attrs["parameter"], r.scene.attrs.get("name", "")
    wall = float(r.meta.get("wall_time", np.nan))
    ax.set_title(f"{title}: spectrum along {name}, {len(p)} values" + (f", {wall:.1f} s" if np.isfinite(wall) else ""))
    print(save(fig, outdir, "lyapunov"))


if __name__ == "__main__":
    main()

"""Lyapunov spectrum along a parameter (run.kind: lyapunov with a grid; /lyapunov in docs/results.md).

    python3 tools/figures/lyapunov.py IN.h5 OUTDIR

Every exponent λ_1 ≥ … ≥ λ_p (per unit time) against the parameter, one colour per index; the
structural exponents (stops held: −∞ exactly, stored as `finite` = 0) are drawn as ▼ on the
bottom edge, and zero as a thin line: a positive λ_1 is chaos.

Checks (the script fails if one does not hold): every point was reached; where the full spectrum
is finite its sum is negative (a damped system with r < 1 contracts phase volume). The order
within a complex pair is not checked: its two QR averages agree only to their finite-time noise.

Writes OUTDIR/lyapunov.png and OUTDIR/lyapunov.pdf.
"""

import numpy as np

from common import args, fail, plt, save
import h5py

COLOURS = ["tab:red", "tab:blue", "tab:green", "tab:purple", "tab:orange", "tab:brown"]


def main():
    (path,), outdir = args(1, 1, "IN.h5 OUTDIR")
    with h5py.File(path, "r") as f:
        if "lyapunov" not in f or "parameter" not in f["lyapunov"]:
            fail(f"{path}: no /lyapunov/parameter (not a run.kind: lyapunov file along a parameter)")
        g = f["lyapunov"]
        p, e, finite, reached = g["parameter"][()], g["exponents"][()], g["finite"][()], g["reached"][()]
        name = g.attrs["parameter"]
        title = f["scene"].attrs.get("name", "")
        wall = float(f["meta"].attrs.get("wall_time", np.nan))
    if not reached.all():
        fail(f"{np.count_nonzero(reached == 0)} points not reached")
    for i in range(len(p)):
        if finite[i].all() and not e[i].sum() < 0.0:
            fail(f"point {i}: the spectrum {e[i]} does not sum to < 0")
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.axhline(0.0, color="0.4", lw=0.6)
    finite_values = e[finite == 1]
    bottom = finite_values.min() - 0.1 * np.ptp(finite_values) if finite_values.size else -1.0
    for i in range(e.shape[1]):
        y = np.where(finite[:, i] == 1, e[:, i], np.nan)
        ax.plot(p, y, "-", marker=".", ms=3, lw=0.8, color=COLOURS[i % len(COLOURS)], label=f"$\\lambda_{{{i + 1}}}$")
        s = finite[:, i] == 0
        if s.any():
            ax.plot(p[s], np.full(s.sum(), bottom), "v", ms=4, color=COLOURS[i % len(COLOURS)], clip_on=False)
    if (finite == 0).any():
        ax.text(0.01, 0.03, "▼: −∞ (structural: a stop held)", transform=ax.transAxes, fontsize=7)
    ax.set_ylim(bottom=bottom - 0.02 * abs(bottom))
    ax.set_xlabel(name)
    ax.set_ylabel("Lyapunov exponent (per unit time)")
    ax.legend(loc="upper left", ncol=e.shape[1])
    ax.set_title(f"{title}: spectrum along {name}, {len(p)} values" + (f", {wall:.1f} s" if np.isfinite(wall) else ""))
    print(save(fig, outdir, "lyapunov"))


if __name__ == "__main__":
    main()

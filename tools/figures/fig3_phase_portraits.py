"""Wagg (2004), fig. 3: phase portrait (x, x') of the orbit of fig. 2, x1 broken and x2 solid,
the stops as vertical lines.

    python3 tools/figures/fig3_phase_portraits.py fig2.h5 OUTDIR   # OUTDIR/fig3_phase_portraits.{png,pdf}
"""
import common as c
import matplotlib.pyplot as plt


def one_orbit(run, per):
    """The samples of the first k periods of a k-periodic orbit (all samples if not periodic), so
    that broken lines are not drawn over themselves out of step."""
    if not per.periodic:
        return run.x, run.v
    t_end = run.t[0] + per.k * run.period
    sel = run.t <= t_end + 1e-9 * run.period
    return run.x[sel], run.v[sel]


def draw_phase(ax, run, scene, per, legend=True):
    x, v = one_orbit(run, per)
    for j in range(scene.m):
        if scene.stop_kind[j] != "between":
            ax.axvline(scene.stop_position[j], color="gray", lw=0.9, ls=(0, (1, 1)) if j % 2 else "-",
                       label=f"stop {scene.stop_name[j]} ({c.mass_label(scene.stop_mass[j])} = {scene.stop_position[j]:g})"
                       if legend else None)
    for i in range(scene.n):
        ax.plot(x[:, i], v[:, i], c.MASS_STYLES[i], color=c.MASS_COLOURS[i], lw=1.0,
                label=f"({c.mass_label(i)}, {c.velocity_label(i)})" if legend else None)
    ax.axhline(0, color="gray", lw=0.4)
    ax.set_xlabel("$x_i$")
    ax.set_ylabel("$\\dot x_i$")


def main():
    (path,), outdir = c.args(1, 1, "FIG2.h5 OUTDIR")
    scene, runs = c.read_runs(path)
    if len(runs) != 1:
        c.fail(f"{path}: expected one simulation, found {len(runs)} runs")
    run = runs[0]
    per = c.periodicity(run)
    fig, ax = plt.subplots(figsize=(5.2, 4.2))
    draw_phase(ax, run, scene, per)
    ax.set_title(f"Wagg (2004) fig. 3: phase portrait, $\\Omega$ = {run.omega:g} ({'one orbit' if per.periodic else 'all recorded periods'})")
    ax.text(0.01, 0.02, per.text(), transform=ax.transAxes, color=per.colour(), fontsize=8)
    ax.legend(loc="upper left", framealpha=0.9)
    out = c.save(fig, outdir, "fig3_phase_portraits")
    rng = ", ".join(f"{c.mass_label(i).strip('$')} in [{run.x[:, i].min():.4f}, {run.x[:, i].max():.4f}], "
                    f"|v| <= {abs(run.v[:, i]).max():.4f}" for i in range(scene.n))
    print(f"fig3 Ω = {run.omega:g}: {per.text()}; {rng}; wrote {out}")


if __name__ == "__main__":
    main()

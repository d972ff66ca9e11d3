"""Wagg (2004), fig. 2: time series of the periodic sticking orbit at Ω = 0.255, x1 broken and
x2 solid, the stops as horizontal lines and the sticking intervals shaded.

    vibro run experiments/wagg2004/fig2_sticking_orbit.yaml -o fig2.h5
    python3 tools/figures/fig2_time_series.py fig2.h5 OUTDIR        # OUTDIR/fig2_time_series.{png,pdf}
"""
import common as c
import matplotlib.pyplot as plt


def main():
    (path,), outdir = c.args(1, 1, "FIG2.h5 OUTDIR")
    scene, runs = c.read_runs(path)
    if len(runs) != 1:
        c.fail(f"{path}: expected one simulation, found {len(runs)} runs")
    run = runs[0]
    per = c.periodicity(run)
    t0 = run.t[0]
    fig, ax = plt.subplots(figsize=(7.5, 3.4))
    c.shade_sticking(ax, run, scene, t_offset=t0)
    c.draw_stops(ax, scene)
    for i in range(scene.n):
        ax.plot(run.t - t0, run.x[:, i], c.MASS_STYLES[i], color=c.MASS_COLOURS[i], lw=1.1, label=c.mass_label(i))
    ax.set_xlim(0, run.t[-1] - t0 + run.t[1] - run.t[0])
    ax.set_xlabel(f"$t - t_0$   ($t_0$ = {t0:.2f} = {round(t0 / run.period)} $T$, $T = 2\\pi/\\Omega$ = {run.period:.3f})")
    ax.set_ylabel("displacement")
    ax.set_title(f"Wagg (2004) fig. 2: sticking orbit, $\\Omega$ = {run.omega:g}")
    ax.text(0.01, 0.03, per.text(), transform=ax.transAxes, color=per.colour(), fontsize=8)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), framealpha=0.9)
    out = c.save(fig, outdir, "fig2_time_series")
    fr = c.sticking_fractions(run, scene)
    print(f"fig2 Ω = {run.omega:g}: {per.text()}; sticking fraction of T: "
          + ", ".join(f"{scene.stop_name[j]} {fr[j]:.5f}" for j in range(scene.m)))
    print(f"  {len(run.contacts['stop'])} sticking intervals over {len(run.pt) - 1} periods; wrote {out}")


if __name__ == "__main__":
    main()

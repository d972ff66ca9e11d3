"""Wagg (2004), fig. 4: the rising sequence. For each Ω of the sweep (0.255, 0.2561, 0.26, 0.27)
the time series (left) and the phase portrait (right), x1 broken and x2 solid, stops and sticking
intervals marked, Ω and the periodicity of the orbit in each panel.

    vibro run experiments/wagg2004/fig4_rising_sequence.yaml -o fig4.h5
    python3 tools/figures/fig4_rising_sequence.py fig4.h5 OUTDIR    # OUTDIR/fig4_rising_sequence.{png,pdf}
"""
import common as c
import matplotlib.pyplot as plt
from fig3_phase_portraits import draw_phase


def main():
    (path,), outdir = c.args(1, 1, "FIG4.h5 OUTDIR")
    scene, runs = c.read_runs(path)
    P = len(runs)
    fig, axes = plt.subplots(P, 2, figsize=(10, 2.6 * P), gridspec_kw={"width_ratios": [2.1, 1]}, squeeze=False)
    letters = "abcdefghijklmnopqrstuvwxyz"
    for p, run in enumerate(runs):
        per = c.periodicity(run)
        t0 = run.t[0]
        ax = axes[p, 0]
        c.shade_sticking(ax, run, scene, t_offset=t0, label=(p == 0))
        c.draw_stops(ax, scene, label=(p == 0))
        for i in range(scene.n):
            ax.plot(run.t - t0, run.x[:, i], c.MASS_STYLES[i], color=c.MASS_COLOURS[i], lw=1.0,
                    label=c.mass_label(i) if p == 0 else None)
        ax.set_xlim(0, run.t[-1] - t0 + run.t[1] - run.t[0])
        ax.set_ylabel("displacement")
        ax.set_title(f"({letters[2 * p]}) $\\Omega$ = {run.omega:g}", loc="left")
        ax.set_title(per.text(), loc="right", color=per.colour(), fontsize=7.5)
        ax2 = axes[p, 1]
        draw_phase(ax2, run, scene, per, legend=(p == 0))
        ax2.set_title(f"({letters[2 * p + 1]}) $\\Omega$ = {run.omega:g}", loc="left")
        ax2.set_title(f"k = {per.k}" if per.periodic else "NOT periodic", loc="right", color=per.colour(), fontsize=7.5)
        fr = c.sticking_fractions(run, scene)
        counts = [len(c.sticking_intervals(run, j)) / max(len(run.pt) - 1, 1) for j in range(scene.m)]
        print(f"fig4 Ω = {run.omega:g}: {per.text()}; sticking fraction "
              + ", ".join(f"{scene.stop_name[j]} {fr[j]:.5f} ({counts[j]:g} intervals/T)" for j in range(scene.m)))
    axes[-1, 0].set_xlabel("$t - t_0$ (start of the recorded periods)")
    axes[0, 0].legend(loc="upper left", bbox_to_anchor=(0.0, 1.32), ncol=6, framealpha=0.9, fontsize=7)
    axes[0, 1].legend(loc="upper left", bbox_to_anchor=(0.0, 1.45), ncol=2, framealpha=0.9, fontsize=7)
    fig.suptitle("Wagg (2004) fig. 4: the rising sequence", y=1.0)
    fig.tight_layout()
    out = c.save(fig, outdir, "fig4_rising_sequence")
    print(f"  wrote {out}")


if __name__ == "__main__":
    main()

"""A long chain that sticks: experiments/chains/chain_1000_sticking.yaml (1000 unit masses and
springs, C = 0.02 K, 0.6 cos 0.8t on mass 0, four stops near the driven end, plastic on mass 1),
run by the modal engine (framework/include/vibro/modal.hpp).

(a) space-time map of the displacements x_i(t) of the first 200 masses: the motion spreads from
    the drive no faster than one mass per time unit (the chain's largest group velocity), so the
    masses beyond the front are exactly at rest and a chain of 100, 1000 or 10 000 masses gives the
    same events near the drive (README, tests/framework/test_modal.cpp);
(b) x_1 and x_2 against their stops, with each contact interval of the plastic stop shaded and the
    impacts marked.

Checks before drawing (the script fails rather than draw unchecked data): the run completed, the
samples are finite, and mass 1 sits on its stop (to 1e-9) at every sample inside a contact interval.

    python3 tools/figures/chain_sticking.py chain_1000_sticking.h5 OUTDIR
"""

import h5py
import matplotlib.pyplot as plt
import numpy as np

import common


def main():
    (path,), outdir = common.args(1, 1, "chain_1000_sticking.h5 OUTDIR")
    with h5py.File(path, "r") as f:
        meta = dict(f["meta"].attrs)
        if meta["status"] != "completed":
            common.fail(f"{path}: run status {meta['status']}: {meta.get('message', '')}")
        t = f["samples/t"][()]
        x = f["samples/x"][()]
        ev_t, ev_stop, ev_kind = f["events/t"][()], f["events/stop"][()], f["events/kind"][()]
        kind_names = [n.decode() if isinstance(n, bytes) else n for n in f["events/kind"].attrs["names"]]
        c_stop, c_start, c_end = f["contacts/stop"][()], f["contacts/t_start"][()], f["contacts/t_end"][()]
        stop_mass = f["scene/stop_mass"][()]
        stop_pos = f["scene/stop_position"][()]
        kind_of = [k.decode() if isinstance(k, bytes) else k for k in f["scene/stop_kind"].attrs["names"]]
        stop_kind = [kind_of[k] for k in f["scene/stop_kind"][()]]
        engine = meta.get("engine", "dense")
    if not np.all(np.isfinite(x)):
        common.fail(f"{path}: non-finite samples")
    n = x.shape[1]
    impact = kind_names.index("impact")

    # Mass 1 must sit on its stop inside every contact interval of the stop on mass 1.
    held = [j for j in range(len(stop_mass)) if stop_mass[j] == 1 and stop_kind[j] in ("upper", "lower")]
    if not held:
        common.fail(f"{path}: no stop on mass 1")
    j1 = held[0]
    worst = 0.0
    for s, a, b in zip(c_stop, c_start, c_end):
        if s != j1:
            continue
        inside = (t > a) & (t < b)
        if inside.any():
            worst = max(worst, np.abs(x[inside, 1] - stop_pos[j1]).max())
    if worst > 1e-9:
        common.fail(f"{path}: mass 1 is {worst:.3g} off its stop while held")

    fig, (ax_a, ax_b) = plt.subplots(2, 1, figsize=(7.0, 6.4), gridspec_kw={"height_ratios": [1.3, 1]})
    shown = min(n, 200)
    lim = np.abs(x[:, :shown]).max()
    im = ax_a.imshow(x[:, :shown].T, aspect="auto", origin="lower", cmap="RdBu_r", vmin=-lim, vmax=lim,
                     extent=[t[0], t[-1], -0.5, shown - 0.5], interpolation="nearest")
    ax_a.plot([t[0], t[-1]], [t[0], t[-1]], "k--", lw=0.8, label="front: one mass per time unit")
    ax_a.set_ylim(-0.5, shown - 0.5)
    ax_a.set_ylabel("mass i")
    ax_a.set_title(f"(a) x_i(t), first {shown} of {n} masses ({engine} engine)")
    ax_a.legend(loc="upper left")
    fig.colorbar(im, ax=ax_a, label="x_i")

    for a, b, s in zip(c_start, c_end, c_stop):
        if s == j1:
            ax_b.axvspan(a, b, color=common.STOP_COLOURS[0], alpha=0.15, lw=0)
    for i, style in ((1, "-"), (2, "--")):
        ax_b.plot(t, x[:, i], style, color="black" if i == 1 else "tab:gray", lw=0.9, label=f"x_{i}")
    for j in range(len(stop_mass)):
        if stop_mass[j] in (1, 2) and stop_kind[j] in ("upper", "lower"):
            ax_b.axhline(stop_pos[j], color=common.STOP_COLOURS[j % len(common.STOP_COLOURS)], lw=0.8,
                         label=f"stop on x_{stop_mass[j]} ({stop_kind[j]})")
            hits = (ev_kind == impact) & (ev_stop == j)
            ax_b.plot(ev_t[hits], np.full(hits.sum(), stop_pos[j]), "v" if stop_kind[j] == "upper" else "^",
                      color=common.STOP_COLOURS[j % len(common.STOP_COLOURS)], ms=3)
    ax_b.set_xlim(t[0], t[-1])
    ax_b.set_xlabel("t")
    ax_b.set_ylabel("x")
    ax_b.set_title(f"(b) masses 1 and 2 at their stops; shaded: mass 1 held ({sum(c_stop == j1)} phases)")
    ax_b.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=4, frameon=False)
    fig.tight_layout()
    print("wrote", common.save(fig, outdir, "chain_1000_sticking"))


if __name__ == "__main__":
    main()

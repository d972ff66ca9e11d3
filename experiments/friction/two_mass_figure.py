"""Two masses with a compliant stop and a frictional contact together: the brute-force diagram in
Ω of two_mass_compliant_friction.yaml (README, "Contact laws and drives beyond the paper's").

    python3 experiments/friction/two_mass_figure.py TWO_MASS.h5 OUT_DIR

The scene is a follow sweep up Ω: at every value, 20 recorded periods after the transient, with
the stroboscopic points (/poincare) and the events (/events: the frictional contact's sticks,
slips and reversals, the compliant stop's engagements). Draws OUT_DIR/two_mass.png (and .pdf):
(a) the stroboscopic x of both masses against Ω; (b) per forcing period, the friction sticks and
the stop's engagements. Prints the ranges of Ω where the recorded motion sticks, where it
touches the stop, and where it does both, and how many values have each least period k ≤ 8 of
the stroboscopic points (to 1e-6 of their scale; "-" where none: not periodic within 8).
"""
import os
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def least_period(points, tolerance):
    """The least k ≤ 8 with the stroboscopic points repeating every k (0 if none)."""
    for k in range(1, 9):
        if len(points) > k and np.max(np.abs(points[k:] - points[:-k])) <= tolerance:
            return k
    return 0


def ranges(omega, mask):
    """The runs of consecutive grid values where mask holds, as (first, last) pairs."""
    out, start = [], None
    for i, m in enumerate(mask):
        if m and start is None:
            start = i
        if not m and start is not None:
            out.append((omega[start], omega[i - 1]))
            start = None
    if start is not None:
        out.append((omega[start], omega[-1]))
    return out


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    path, out = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    with h5py.File(path, "r") as f:
        omega = f["sweep/values"][:, 0]
        status = f["sweep/status"][:]
        x = f["poincare/x"][:]
        rows = f["poincare/rows"][:]
        periods = float(f["scene"].attrs["periods"])
        names = [n.decode() if isinstance(n, bytes) else n for n in f["events/kind"].attrs["names"]]
        kind = f["events/kind"][:]
        point = f["events/point"][:]
    if np.any(status != 0):
        sys.exit(f"{np.count_nonzero(status)} points stopped early")
    P = len(omega)
    per = {}
    for name in ("friction-stick", "engage"):
        code = names.index(name)
        per[name] = np.bincount(point[kind == code], minlength=P) / periods
    scale = np.nanmax(np.abs(x))
    k = np.array([least_period(x[p, : rows[p]].reshape(rows[p], -1), 1e-6 * scale) for p in range(P)])

    fig, (a, b) = plt.subplots(2, 1, figsize=(7, 6.5), sharex=True)
    for j, colour in ((0, "C0"), (1, "C3")):
        for p in range(P):
            a.plot(np.full(rows[p], omega[p]), x[p, : rows[p], j], ",", color=colour)
        a.plot([], [], ".", color=colour, label=f"x{j}")
    a.axhline(0.5, color="0.5", lw=0.6, ls="--")
    a.set_ylabel("stroboscopic x")
    a.legend(loc="upper right")
    a.set_title("(a) brute-force diagram (follow sweep up Ω)")
    b.plot(omega, per["friction-stick"], ".-", ms=3, label="friction sticks per period (mass 0)")
    b.plot(omega, per["engage"], ".-", ms=3, label="stop engagements per period (mass 1)")
    b.set_xlabel("Ω")
    b.set_ylabel("events per period")
    b.legend(loc="upper right")
    b.set_title("(b) stick-slip and contact")
    fig.tight_layout()
    for ext in ("png", "pdf"):
        fig.savefig(os.path.join(out, f"two_mass.{ext}"), dpi=150)

    fmt = lambda rs: ", ".join(f"[{lo:.2f}, {hi:.2f}]" for lo, hi in rs) or "none"  # noqa: E731
    stick = per["friction-stick"] > 0
    touch = per["engage"] > 0
    print(f"{P} values of Omega in [{omega[0]:.2f}, {omega[-1]:.2f}]")
    print(f"sticks: {np.count_nonzero(stick)} values, {fmt(ranges(omega, stick))}")
    print(f"touches the stop: {np.count_nonzero(touch)} values, {fmt(ranges(omega, touch))}")
    print(f"both: {np.count_nonzero(stick & touch)} values, {fmt(ranges(omega, stick & touch))}")
    counts = {int(v): int(c) for v, c in zip(*np.unique(k, return_counts=True))}
    print("least period: " + ", ".join(f"{'-' if v == 0 else v}: {c}" for v, c in sorted(counts.items())))
    print(f"most sticks per period {per['friction-stick'].max():.2f} (Omega = {omega[np.argmax(per['friction-stick'])]:.2f}), "
          f"most engagements per period {per['engage'].max():.2f} (Omega = {omega[np.argmax(per['engage'])]:.2f})")


if __name__ == "__main__":
    main()

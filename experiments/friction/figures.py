"""Den Hartog's forced oscillator with Coulomb and viscous friction: the sweep of den_hartog.yaml
against his closed form (README, "Dry friction: Den Hartog's response curves").

    python3 experiments/friction/figures.py DEN_HARTOG.h5 OUT_DIR

Den Hartog (1931), "Forced vibrations with combined Coulomb and viscous friction", Trans. ASME 53,
APM-53-9, 107–115: the steady motion without stops of m x'' + c x' + k x = F0 cos Ωt − F_f sgn x'
is symmetric, x(t + T/2) = −x(t). On the half period from its lowest point t1 (x' = 0, then
x' > 0) the friction is the constant −F_f, so x = X cos(Ωt − ψ) − F_f/k + h(t − t1), with X, ψ
the viscous system's forced response and h a free motion; symmetry gives (I + Φ(T/2)) (h0, h0')
= (2F_f/k, 0), Φ the free motion's transition matrix, and x'(t1) = 0 gives sin(Ωt1 − ψ) =
h0'/(XΩ) (derived here in his way; the same derivation as tests/framework/test_friction.cpp).
The solution holds where it exists (|h0'| ≤ XΩ) and its velocity stays positive over the half
period: that is his boundary of motion without stops.

Draws OUT_DIR/den_hartog.png (and .pdf): (a) the amplitude max|x| against Ω for each friction
ratio F_f/F0, the closed form (lines, where it holds) and the simulations (markers); (b) the
(Ω, F_f/F0) plane: Den Hartog's boundary and every swept point, marked by whether its simulated
steady motion stopped. Checks (exits 1 if one fails): where the closed form holds, every recorded
sample of the simulation equals it (max |Δx| over the amplitude, printed); a point whose motion
stops lies where the closed form does not hold, and one moving without stops where it does.
"""
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


class DenHartog:
    """The steady motion without stops (module docstring), or valid = False where there is none."""

    def __init__(self, m, c, k, F0, Ff, W):
        self.k, self.Ff, self.W = k, Ff, W
        re, im = k - m * W * W, c * W
        self.X = F0 / math.hypot(re, im)
        self.psi = math.atan2(im, re)
        self.T = 2 * math.pi / W
        w0 = math.sqrt(k / m)
        self.zw = zw = c / (2 * m)
        self.wd = wd = math.sqrt(w0 * w0 - zw * zw)
        s = self.T / 2
        e, cs, sn = math.exp(-zw * s), math.cos(wd * s), math.sin(wd * s)
        p00, p01 = e * (cs + zw / wd * sn), e * sn / wd
        p10, p11 = -e * (w0 * w0 / wd) * sn, e * (cs - zw / wd * sn)
        a00, a01, a10, a11 = 1 + p00, p01, p10, 1 + p11
        det = a00 * a11 - a01 * a10
        r0 = 2 * Ff / k
        self.h0, self.h1 = a11 * r0 / det, -a10 * r0 / det
        sv = self.h1 / (self.X * W)
        self.valid = abs(sv) <= 1.0
        if not self.valid:
            return
        base = math.asin(sv)
        self.t1 = None
        for ang in (base, math.pi - base):
            acc = -self.X * W * W * math.cos(ang) + (-2 * zw * self.h1 - w0 * w0 * self.h0)
            if acc > 0:
                self.t1 = (ang + self.psi) / W
        if self.t1 is None:
            self.valid = False
            return
        # Without stops: x' > 0 over the open half period from t1.
        s = np.linspace(0.0, self.T / 2, 2001)[1:-1]
        self.valid = bool((self.at(self.t1 + s)[1] > 0).all())

    def at(self, t):
        """x(t), x'(t) of the steady motion (arrays)."""
        t = np.asarray(t, float)
        s = np.mod(t - self.t1, self.T)
        second = s >= self.T / 2
        sign = np.where(second, -1.0, 1.0)
        s = np.where(second, s - self.T / 2, s)
        t = np.where(second, t - self.T / 2, t)
        e, cs, sn = np.exp(-self.zw * s), np.cos(self.wd * s), np.sin(self.wd * s)
        b = (self.h1 + self.zw * self.h0) / self.wd
        h = e * (self.h0 * cs + b * sn)
        hd = e * (-self.zw * (self.h0 * cs + b * sn) + self.wd * (-self.h0 * sn + b * cs))
        x = self.X * np.cos(self.W * t - self.psi) - self.Ff / self.k + h
        v = -self.X * self.W * np.sin(self.W * t - self.psi) + hd
        return sign * x, sign * v


def boundary(m, c, k, F0, omegas):
    """Den Hartog's boundary: per Ω, the largest F_f/F0 with motion without stops (bisection)."""
    out = []
    for W in omegas:
        lo, hi = 0.0, 1.0
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if DenHartog(m, c, k, F0, mid * F0, W).valid else (lo, mid)
        out.append(lo)
    return np.array(out)


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: figures.py DEN_HARTOG.h5 OUT_DIR")
    import h5py
    path, out = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    with h5py.File(path, "r") as f:
        s = f["scene"]
        m, c, k = float(s["mass"][0, 0]), float(s["damping"][0, 0]), float(s["stiffness"][0, 0])
        F0 = float(s["forcing_cosine"][0])
        sw = f["sweep"]
        values, status = sw["values"][()], sw["status"][()]
        if (status != 0).any():
            sys.exit(f"error: {int((status != 0).sum())} sweep points stopped early")
        srows, st, sx = f["samples/rows"][()], f["samples/t"][()], f["samples/x"][()]
        erows, ekind = f["events/rows"][()], f["events/kind"][()]
        names = [n.decode() if isinstance(n, bytes) else n for n in f["events/kind"].attrs["names"]]
    stick = names.index("friction-stick")
    ends = np.concatenate([[0], np.cumsum(erows)])
    loads = sorted(set(values[:, 0]))
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.6))
    worst, agree, mismatched = 0.0, 0, []
    for i, load in enumerate(loads):
        rows = np.nonzero(values[:, 0] == load)[0]
        W = values[rows, 1]
        amp_sim, stops = [], []
        for p in rows:
            t, x = st[p, :srows[p]], sx[p, :srows[p], 0]
            amp_sim.append(np.abs(x).max())
            stopped = bool((ekind[ends[p]:ends[p + 1]] == stick).any())
            stops.append(stopped)
            dh = DenHartog(m, c, k, F0, load, values[p, 1])
            if dh.valid:
                err = np.abs(dh.at(t)[0] - x).max() / np.abs(x).max()
                worst = max(worst, err)
                agree += 1
            if dh.valid == stopped:
                mismatched.append((load, values[p, 1], "stops" if stopped else "moves without stops"))
        colour = f"C{i}"
        grid = np.linspace(W.min(), W.max(), 600)
        curve = np.array([np.nan if not (d := DenHartog(m, c, k, F0, load, w)).valid
                          else np.abs(d.at(d.t1 + np.linspace(0, d.T / 2, 801))[0]).max() for w in grid])
        a.plot(grid * math.sqrt(m / k), curve / (F0 / k), "-", color=colour, lw=1.0,
               label=f"$F_f/F_0$ = {load / F0:g}: closed form")
        stops = np.array(stops)
        amp_sim = np.array(amp_sim) / (F0 / k)
        a.plot(W[~stops] * math.sqrt(m / k), amp_sim[~stops], "o", ms=3, color=colour, mfc="none")
        a.plot(W[stops] * math.sqrt(m / k), amp_sim[stops], "x", ms=4, color=colour)
        b.plot(W[~stops], np.full((~stops).sum(), load / F0), "o", ms=3, color="tab:blue", mfc="none")
        b.plot(W[stops], np.full(stops.sum(), load / F0), "x", ms=4, color="tab:red")
    a.set_yscale("log")
    a.set_xlabel(r"$\Omega / \omega_0$")
    a.set_ylabel(r"amplitude max$|x|$ / $(F_0/k)$")
    a.set_title("(a) closed form (lines), simulations (o: no stops, x: stops)", fontsize=9)
    a.legend(fontsize=7)
    omegas = np.linspace(values[:, 1].min(), values[:, 1].max(), 300)
    b.plot(omegas, boundary(m, c, k, F0, omegas), "k-", lw=1.0, label="Den Hartog's boundary of motion without stops")
    b.set_xlabel(r"$\Omega$")
    b.set_ylabel(r"$F_f/F_0$")
    b.set_ylim(0, 1)
    b.set_title("(b) o: moves without stops, x: stops each period", fontsize=9)
    b.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    for ext in ("png", "pdf"):
        fig.savefig(os.path.join(out, f"den_hartog.{ext}"), bbox_inches="tight", dpi=130)
    print(os.path.join(out, "den_hartog.png"))
    print(f"points: {len(values)}; without stops by the closed form: {agree}; largest |x_sim − x_DenHartog| over "
          f"the amplitude there: {worst:.2e}")
    print(f"points whose simulated stops disagree with the closed form's boundary: {len(mismatched)}")
    for item in mismatched:
        print(f"  F_f = {item[0]:g}, Ω = {item[1]:.6g}: the simulation {item[2]}")
    if worst > 1e-8 or mismatched:
        sys.exit(1)


if __name__ == "__main__":
    main()

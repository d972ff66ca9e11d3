"""The period doublings of the three-mass clearance chain's period-1 branch, located by continuation
(experiments/examples/three_mass_clearance_continuation.yaml, from the non-sticking orbit at Ω = 0.7
down to 0.3), held against computations of their own:

    /usr/bin/python3 tools/figures/clearance_doublings.py SCENE DIAGRAM.h5 CONTINUATION.h5

SCENE is the continuation's scene file, DIAGRAM.h5 the brute-force up/down diagram of the same
chain over the same range (experiments/examples/three_mass_clearance_diagram.yaml), CONTINUATION.h5
the continuation's result. The script fails (exit 1) unless both parts below hold.

1. Every period doubling on the period-1 branch (branch 0), located or bisected, is checked by
   finite differences: at two values of Ω, one on each side of its bracket, its orbit is found by
   Newton shooting (vibro.shoot) and the Jacobian of the period map by central differences of runs
   of one forcing period (the end state of vibro.tangent_map: the integrator and its events only,
   not the saltation matrices that continuation's multipliers come from). The eigenvalue nearest
   −1 must lie below −1 on one side and above on the other, each on the side of −1 where the exact
   multiplier lies, by more than its uncertainty (two step sizes) and its difference from the
   exact one. The two values are the bracket's ends, widened by steps of 4 from 1e-10 until the
   exact multiplier lies AWAY from −1, never up to another located change of the branch (at a
   grazing the multiplier jumps) nor into complex multipliers.
2. Every change of period 1 ↔ 2 between neighbouring values of one sweep of the diagram is
   accounted for. The branch's orbits at the period-1 value are shot from the branch's points
   around it (x_fixed, v_fixed: phase 0, the diagram's stroboscopic phase); the diagram's point is
   on the branch where it lies within SAME of one of them, and that orbit is shot on to the
   period-2 value. In this order:
   * a doubling located (or bisected, its whole bracket) inside the interval;
   * the period-1 point is not on the branch: another attractor;
   * the branch's orbit is stable at the period-2 value: that value is run again from its recorded
     state with the diagram's own period test after RERUN periods. Period 1 on the branch's orbit:
     slow settling (a multiplier near −1 leaves an alternation decaying so slowly that it passes
     the test for period 2 first), and the next interval of the sweep is examined in its place
     (where the diagram still changes period there). Still period 2: a period-2 attractor beside
     the stable branch, not a doubling of it (the folds and grazings continuation of that 2T orbit
     locates inside the interval are printed beside it);
   * the branch's orbit at the period-2 value has a real multiplier below −1 and no other outside
     the unit circle, it is stable at the period-1 value, and a grazing is located in the interval:
     the multiplier jumps past −1 at the grazing (on the side with the impact the grazing adds, a
     multiplier tends to −∞ as the impact's speed goes to 0: Nordmark 1991);
   * anything else is not accounted for.
"""

import re
import sys

import h5py
import numpy as np

from common import vibro_module

# How near the diagram's period-1 point must lie to an orbit of the branch (max over x and v at
# phase 0) to be that orbit: the diagram accepts a period at 1e-6 relative to L = 0.4 and V = LΩ
# (≤ 4e-7 in x and v here), and a settled orbit lies within a few of its own repeats of the exact
# one; distinct orbits of this chain at one Ω differ by 1e-2 and more (printed where one is found).
SAME = 1e-5
# Periods the diagram's period test is rerun after at a value where the branch is stable: 10 × the
# diagram's transient (200). The slowest decay met here, |μ| ≈ 0.975 at Ω = 0.545, shrinks a
# transient by 1e-22 in 2000 periods.
RERUN = 2000
# How far from −1 the exact multiplier must lie at both values of the finite-difference check
# (the bracket widened by steps of 4 from 1e-10 until it does): the differences' own uncertainty
# is ~1e-4 away from grazings and grows near them (the map's second derivative grows like 1/u³,
# u the slowest impact's speed), where it is measured (steps H and H/10) and compared.
AWAY = 0.01
# A period-2 attractor beside a stable stretch of the branch is followed by continuation over its
# value ± SPAN (10 grid steps; the scaled steps are relative to that range).
SPAN = 5e-3
H = 1e-9  # the finite differences' step in x and v (t and Ω of order 1, states of order 0.5)


def fail(message):
    sys.stderr.write(f"error: {message}\n")
    sys.exit(1)


def nearest_minus_one(values):
    values = np.asarray(values)
    return values[np.argmin(np.abs(values + 1.0))]


class Chain:
    """The scene at any Ω: shooting, exact and finite-difference multipliers, diagram reruns."""

    def __init__(self, vibro, path):
        self.vibro = vibro
        self.scene = vibro.Scene.load(path)
        with open(path) as f:
            self.text = f.read()

    def at(self, w):
        s = self.scene.copy()
        s.set("forcing.frequency", float(w))
        return s

    def shoot(self, w, t, x, v, phase):
        o = self.vibro.shoot(self.at(w), x, v, t=t, phase=phase, tolerance=1e-12)
        return o if o.status == "converged" else None

    def fd_multiplier(self, w, o):
        """The eigenvalue nearest −1 of the period map's central-difference Jacobian at the orbit o
        (steps H and H/10) and its uncertainty (their difference); None if a run fails."""
        s = self.at(w)
        z = np.hstack([o.x, o.v])
        found = []
        for h in (H, 0.1 * H):
            J = np.empty((6, 6))
            for j in range(6):
                ends = []
                for sign in (1.0, -1.0):
                    zz = z.copy()
                    zz[j] += sign * h
                    m = self.vibro.tangent_map(s, zz[:3], zz[3:], t0=o.t0, periods=1)
                    if m.status != "completed":
                        return None
                    ends.append(np.hstack([m.x1, m.v1]))
                J[:, j] = (ends[0] - ends[1]) / (2.0 * h)
            found.append(nearest_minus_one(np.linalg.eigvals(J)))
        return found[1], abs(found[1] - found[0])

    def attractor_turn(self, w, z, toward, lo, hi):
        """The folds and grazings inside [lo, hi] of a period-2 attractor of the diagram (state z at
        phase 0, value w): its orbit followed by continuation (period 2) from w towards `toward`
        over w ± SPAN ('' if none: the text is only what continuation locates there)."""
        text = self.text[:self.text.index("\ninitial:")] + (
            "\ninitial:\n  x: [" + ", ".join(repr(float(q)) for q in z[:3]) + "]\n  v: ["
            + ", ".join(repr(float(q)) for q in z[3:]) + "]\n"
            "run:\n  kind: continue\n  continue:\n    path: forcing.frequency\n"
            f"    range: [{w - SPAN!r}, {w + SPAN!r}]\n    period: 2\n    max_doublings: 0\n"
            f"    direction: {'down' if toward < w else 'up'}\n    max_points: 400\n")
        # (the scene's forcing.frequency, a line of its own, set to w)
        text = re.sub(r"\n  frequency: [^\n]*", f"\n  frequency: {float(w)!r}", text, count=1)
        r = self.vibro.continuation(self.vibro.Scene.from_text(text), progress=False)
        p = r["branch/p"]
        if len(p) < 3:
            return ""
        # What it locates inside [lo, hi] (each value once: a branch may pass a grazing twice).
        names = list(r.attributes("bifurcations/kind")["names"])
        rows = zip(r["bifurcations/kind"], r["bifurcations/p"])
        found = sorted({(names[int(kk)], round(float(q), 10)) for kk, q in rows
                        if lo <= q <= hi and names[int(kk)] in ("fold", "grazing")}, key=lambda e: e[1])
        if not found:
            return ""
        return ("; continuation of that 2T orbit locates between the two values: "
                + ", ".join(f"{kind} at {q:.10f}" for kind, q in found))

    def rerun(self, w, x, v):
        """The diagram's period test at w after RERUN periods from (x, v) at phase 0."""
        s = self.at(w)
        s.update({**{f"initial.x[{j}]": float(x[j]) for j in range(3)},
                  **{f"initial.v[{j}]": float(v[j]) for j in range(3)}})
        # Two values (a diagram needs them), the second 1e-9 above and not read.
        d = self.vibro.diagram(s, path="forcing.frequency", values=[float(w), float(w) + 1e-9],
                               directions="up", transient=0, transient_periods=RERUN, threads=1)
        g = d["diagram"]
        return int(g["k_up"][0]), np.hstack([g["x_up"][0][-1], g["v_up"][0][-1]])


def check_doublings(chain, marks):
    """Part 1: each doubling of branch 0 against finite-difference multipliers."""
    others = sorted(m["p"] for m in marks if m["kind"] != "period_doubling" and m["branch"] == 0)
    bad = []
    for m in sorted((m for m in marks if m["kind"] == "period_doubling" and m["branch"] == 0), key=lambda m: m["p"]):
        p = m["p"]
        # The nearest other located change on either side bounds the widening.
        below = max([q for q in others if q < m["p_low"]], default=-np.inf)
        above = min([q for q in others if q > m["p_high"]], default=np.inf)
        half, ends = 0.0, None
        while half <= 1e-3:
            lo, hi = m["p_low"] - half, m["p_high"] + half
            if lo <= below or hi >= above:
                break
            pair = [chain.shoot(w, m["t0"], m["x"], m["v"], m["phase"]) for w in (lo, hi)]
            if not all(pair):
                break
            exact = [nearest_minus_one(o.multipliers.values) for o in pair]
            if any(abs(e.imag) > 0.0 for e in exact):
                break
            ends = (lo, hi, pair, exact)
            if min(abs(e + 1.0) for e in exact) >= AWAY:
                break
            half = max(4.0 * half, 1e-10)
        how = "located" if m["smooth"] else f"bisected, bracket {m['p_high'] - m['p_low']:.1e}"
        if ends is None:
            print(f"  {p:.10f} ({how}): NOT CHECKED (no orbit found beside it short of the next change)")
            bad.append(p)
            continue
        lo, hi, pair, exact = ends
        fd = [chain.fd_multiplier(w, o) for w, o in zip((lo, hi), pair)]
        # Each finite-difference multiplier real and on its exact one's side of −1, by more than
        # both its own uncertainty and its difference from the exact one.
        sides = [f is not None and abs(f[0].imag) < 1e-6 and abs(f[0] + 1.0) > max(f[1], abs(f[0] - e))
                 and (f[0].real + 1.0) * (e.real + 1.0) > 0.0 for f, e in zip(fd, exact)]
        crosses = all(sides) and (exact[0].real + 1.0) * (exact[1].real + 1.0) < 0.0
        text = ", ".join(f"{f[0].real:+.4f} (exact {e.real:+.4f}) at {w:.10f}" if f is not None
                         else f"no map at {w:.10f}" for f, e, w in zip(fd, exact, (lo, hi)))
        print(f"  {p:.10f} ({how}): finite-difference multiplier {text}: "
              + ("crosses −1" if crosses else "DOES NOT CROSS −1"))
        if not crosses:
            bad.append(p)
    return bad


def branch_orbits(chain, b, w):
    """The branch's orbits at w: one shot from each pair of neighbouring points around w."""
    p = b["p"]
    found = []
    for i in range(len(p) - 1):
        if b["branch"][i] != 0 or b["branch"][i + 1] != 0 or not b["fixed_ok"][i] or not b["fixed_ok"][i + 1]:
            continue
        if (p[i] - w) * (p[i + 1] - w) > 0.0 or p[i] == p[i + 1]:
            continue
        s = (w - p[i]) / (p[i + 1] - p[i])
        z = b["z"][i] + s * (b["z"][i + 1] - b["z"][i])
        o = chain.shoot(w, 0.0, z[:3], z[3:], 0.0)
        if o is None:
            continue
        zo = np.hstack([o.x, o.v])
        if all(np.max(np.abs(zo - f[0])) > SAME for f in found):
            found.append((zo, o))
    return found


def describe(o):
    mu = np.asarray(o.multipliers.values)
    out = mu[np.abs(mu) > 1.0]
    if len(out) == 0:
        return "stable", f"|μ| ≤ {np.max(np.abs(mu)):.3f}"
    if len(out) == 1 and abs(out[0].imag) < 1e-12 and out[0].real < -1.0:
        return "flip", f"μ = {out[0].real:.4g}"
    return "unstable", "μ outside: " + ", ".join(f"{m:.3g}" for m in out)


def main():
    if len(sys.argv) != 4:
        fail("usage: clearance_doublings.py SCENE DIAGRAM.h5 CONTINUATION.h5")
    vibro = vibro_module()
    with h5py.File(sys.argv[2], "r") as f:
        g = f["diagram"]
        W = g["parameter"][()]
        sweeps = {s: (g[f"x_{s}"][()], g[f"v_{s}"][()], g[f"k_{s}"][()]) for s in ("up", "down")}
    with h5py.File(sys.argv[3], "r") as f:
        bf = f["bifurcations"]
        names = [n.decode() if isinstance(n, bytes) else n for n in bf["kind"].attrs["names"]]
        marks = [dict(row=i, kind=names[int(bf["kind"][i])], p=float(bf["p"][i]), p_low=float(bf["p_low"][i]),
                      p_high=float(bf["p_high"][i]), branch=int(bf["branch"][i]), smooth=int(bf["smooth"][i]),
                      t0=float(bf["t0"][i]), phase=float(bf["phase"][i]), x=bf["x"][i], v=bf["v"][i])
                 for i in range(len(bf["p"]))]
        br = f["branch"]
        b = dict(p=br["p"][()], branch=br["branch"][()], fixed_ok=br["fixed_ok"][()],
                 z=np.hstack([br["x_fixed"][()], br["v_fixed"][()]]))
    doublings = sorted((m for m in marks if m["kind"] == "period_doubling" and m["branch"] == 0), key=lambda m: m["p"])
    chain = Chain(vibro, sys.argv[1])
    located = [m["p"] for m in doublings if m["smooth"]]
    print(f"continuation: {len(doublings)} period doublings on the period-1 branch, {len(located)} located, "
          f"{len(doublings) - len(located)} bisected")
    bad = check_doublings(chain, marks)

    def doubling_in(lo, hi):
        # (a bisected one by its whole bracket)
        return [m["p"] for m in doublings if lo <= m["p_low"] and m["p_high"] <= hi]

    def grazings_in(lo, hi):
        return [m["p"] for m in marks if m["kind"] == "grazing" and m["branch"] == 0 and lo <= m["p"] <= hi]

    counts = {}
    missed = []
    print("diagram: every change of period 1 ↔ 2 between neighbouring values of a sweep")
    for sweep, (x, v, k) in sweeps.items():
        order = range(len(W) - 1) if sweep == "up" else range(len(W) - 1, 0, -1)
        step = 1 if sweep == "up" else -1
        for i in order:
            j = i + step
            if sorted((int(k[i]), int(k[j]))) != [1, 2]:
                continue
            head = f"  {sweep:4s} {int(k[i])} → {int(k[j])} between Ω = {W[i]:.4f} and {W[j]:.4f}: "
            verdict, text = examine(chain, b, W, x, v, k, i, j, doubling_in, grazings_in)
            counts[verdict] = counts.get(verdict, 0) + 1
            print(head + text)
            if verdict == "not accounted for":
                missed.append(f"{sweep} [{min(W[i], W[j]):.4f}, {max(W[i], W[j]):.4f}]")
    print("summary: " + ", ".join(f"{n} {v}" for v, n in counts.items()))
    if bad:
        fail("doublings the finite differences do not confirm: " + ", ".join(f"{p:.10f}" for p in bad))
    if missed:
        fail("changes of period 1 ↔ 2 not accounted for: " + ", ".join(missed))


def examine(chain, b, W, x, v, k, i, j, doubling_in, grazings_in, z_one=None, depth=0):
    """One change of period between W[i] and W[j] (the sweep's order): (verdict, explanation).
    z_one: the period-1 point where it comes from a rerun (slow settling), else the recorded one."""
    one, two = (i, j) if k[i] == 1 or z_one is not None else (j, i)
    lo, hi = min(W[i], W[j]), max(W[i], W[j])
    inside = doubling_in(lo, hi)
    if inside:
        return "doubling located", f"doubling located at {inside[0]:.10f}"
    z1 = np.hstack([x[one][-1], v[one][-1]]) if z_one is None else z_one
    orbits = branch_orbits(chain, b, W[one])
    dist = [float(np.max(np.abs(z - z1))) for z, _ in orbits]
    if not orbits or min(dist) > SAME:
        return ("another attractor",
                f"the period-1 point at {W[one]:.4f} is not the branch's: {min(dist, default=np.inf):.1e} "
                f"from the nearest of its {len(orbits)} orbits there")
    o1 = orbits[int(np.argmin(dist))][1]
    o2 = chain.shoot(W[two], 0.0, o1.x, o1.v, 0.0)
    if o2 is None:
        return "not accounted for", f"the branch's orbit at {W[one]:.4f} has none at {W[two]:.4f}"
    kind1, mu1 = describe(o1)
    kind2, mu2 = describe(o2)
    if kind2 == "stable":
        # The branch's orbit is an attractor at the period-2 value: run it again for longer.
        period, z = chain.rerun(W[two], x[two][-1], v[two][-1])
        on = min(float(np.max(np.abs(zz - z))) for zz, _ in branch_orbits(chain, b, W[two])) if period == 1 else np.inf
        if period != 1 or on > SAME:
            text = (f"the branch's orbit is stable at {W[two]:.4f} ({mu2}) and at {W[one]:.4f} ({mu1}); "
                    f"{RERUN} periods more stay on period {period}: a period-2 attractor beside it, "
                    "not a doubling of the branch")
            z2 = np.hstack([x[two][-1], v[two][-1]])
            return "period-2 attractor beside the branch", text + chain.attractor_turn(W[two], z2, W[one], lo, hi)
        text = (f"slow settling: the branch's orbit is stable at {W[two]:.4f} ({mu2}); {RERUN} periods more give "
                f"period 1 on it ({on:.0e} away)")
        nxt = two + (two - one)
        if not (0 <= nxt < len(W)) or k[nxt] != 2 or depth >= 3:
            return "slow settling", text + ": no change of period 1 ↔ 2 here"
        verdict, rest = examine(chain, b, W, x, v, k, two, nxt, doubling_in, grazings_in, z, depth + 1)
        return (verdict if verdict == "not accounted for" else "slow settling",
                text + f"; then between {W[two]:.4f} and {W[nxt]:.4f}: " + rest)
    graze = grazings_in(lo, hi)
    if kind2 == "flip" and kind1 == "stable" and graze:
        return ("multiplier jumps past −1 at a grazing",
                f"grazing at {graze[0]:.10f}: the branch's orbit is stable at {W[one]:.4f} ({mu1}), "
                f"at {W[two]:.4f} {mu2}: the multiplier jumps past −1 at the grazing")
    return "not accounted for", f"the branch at {W[one]:.4f}: {kind1} ({mu1}); at {W[two]:.4f}: {kind2} ({mu2})" + (
        f"; grazings located there: {', '.join(f'{g:.10f}' for g in graze)}" if graze else "")


if __name__ == "__main__":
    main()

"""Two-parameter curves of the paper's system (Wagg 2004) in the plane (Ω, A1): the rising of mass 1
(multi-sliding bifurcation on its stop s1) and the grazing corner of mass 1 near Ω ≈ 0.2637, each
located on the branch in Ω at the paper's A1 = 0.5 and followed in A1 by run.continue.curve
(experiments/wagg2004/rising_curve.yaml); checked at chosen curve points by independent runs at
fixed A1.

Inputs, told apart by their content:
  * curve files (/curve): `vibro run experiments/wagg2004/rising_curve.yaml` (and its grazing run);
  * check files at one A1 each, equal to a curve point's A1 (its /scene forcing_cosine[0]):
      - `run.kind: locate` files (/transitions): the running method (orbits by running until they
        repeat, transitions bracketed by bisection on their sticking phases), an algorithm
        independent of the continuation: its rising of s1 must bracket the curve point's Ω to
        within its own bracket width (plus 1e-9);
      - `run.kind: continue` files without /curve: the branch in Ω at that A1; its rising or
        grazing of s1 nearest the curve point must agree with the curve point's Ω to 1e-9.
The script prints every comparison, draws the figure, and then fails (exit 1) if one did not hold, or if a check file's A1 is not
that of a curve point. With --build BUILD_DIR (the vibro Python module), every grazing orbit that
a file holds (the curve's starting point, the continue checks' grazings) is also run for one period
from its state, and its nearest approach to the stop in free flight (away from the stop's events)
must be ≤ 1e-9·(stop position scale): the orbit touches the stop there.

Figure two_parameter: (a) the curves in (Ω, A1), the paper's point (A1 = 0.5, the rising at
Ω = 0.2560063) and line marked, the curve's ends labelled, the check points ringed; (b) the
checks' differences |Ω_check − Ω_curve| against A1 (log scale) with the locate brackets.

    python3 tools/figures/two_parameter.py [--build BUILD_DIR] rising_curve.h5 grazing_curve.h5 check_*.h5 OUTDIR
"""
import os
import sys

import common as c
import h5py
import matplotlib.pyplot as plt
import numpy as np

PAPER_A1 = 0.5
PAPER_RISING = 0.2560063298          # the branch's rising at A1 = 0.5 (README, continuation table)
CONTINUE_TOL = 1e-9
LOCATE_MARGIN = 1e-9
KIND_NAMES = {3: "grazing", 4: "rising"}
COLOURS = {("rising", 0): "tab:blue", ("grazing", 0): "tab:orange", ("rising", 1): "tab:green",
           ("grazing", 1): "tab:red"}


def text(v):
    return v.decode() if isinstance(v, bytes) else str(v)


def read_curves(path):
    with h5py.File(path, "r") as f:
        c.check_status(f, path)
        g = f["curve"]
        p1, p2 = text(g.attrs["p1"]), text(g.attrs["p2"])
        if p1 != "forcing.frequency" or p2 != "forcing.cosine[0]":
            c.fail(f"{path}: a curve in ({p1}, {p2}), not (forcing.frequency, forcing.cosine[0])")
        ends = [text(e) for e in g["curve"].attrs.get("end", [])]
        d = {k: g[k][()] for k in ("curve", "kind", "stop", "p1", "p2", "value")}
        names = [text(n) for n in f["bifurcations/kind"].attrs["names"]]
    curves = []
    for ci in np.unique(d["curve"]):
        s = d["curve"] == ci
        curves.append({"kind": names[int(d["kind"][s][0])], "stop": int(d["stop"][s][0]), "p1": d["p1"][s],
                       "p2": d["p2"][s], "value": d["value"][s], "end": ends[int(ci)] if int(ci) < len(ends) else "",
                       "file": path})
    return curves


def nearest_approach(vibro, f, i):
    """The located orbit i of /bifurcations of file f, run from its state: its least distance to
    its stop at a touch in free flight, that is at an interior minimum of the gap within a flight
    (between two events of that stop, starting at an impact or a release), refined on a fine grid
    around it; or, if less, the overshoot u²/(2|g''|) of its slowest impact on that stop — a run of
    an orbit located at a grazing may register the touch itself as an impact of speed u ≈ 0 (the
    three-mass chain's grazing at Ω ≈ 0.18414: u = 1.8e-7), and the free trajectory would then have
    passed the stop by that overshoot, the grazing condition's own residual. A real impact
    (u ~ 0.1 V) overshoots by far more than any tolerance here.
    The gap at an impact is zero too, but there the mass arrives and leaves at a speed: a touch is
    where the gap turns (its rate changes sign from falling to rising) in free flight. Each flight is sampled geometrically towards both of its
    ends, so that a touch a little after a bounce of a fast sequence (the paper's system at
    Ω ≈ 0.257456: bounces 2e-4 T apart, the touch 2e-4 T after the last) is seen as the
    minimum it is rather than hidden beside that bounce's event."""
    sc = f["scene"]
    kinds = [text(n) for n in sc["stop_kind"].attrs["names"]]
    stops = []
    for j in range(len(sc["stop_mass"])):
        kind = kinds[int(sc["stop_kind"][j])]
        if kind == "between":
            c.fail("stops between masses are not handled here")
        stops.append({"mass": int(sc["stop_mass"][j]), "side": kind, "position": float(sc["stop_position"][j]),
                      "restitution": float(sc["stop_restitution"][j]), "name": text(sc["stop_name"][j])})
    bi = f["bifurcations"]
    j = int(bi["stop"][i])
    omega = float(bi["p"][i])
    t0 = float(bi["t0"][i])
    s = vibro.Scene.from_matrices(sc["mass"][()], sc["damping"][()], sc["stiffness"][()], frequency=omega,
                                  cosine=sc["forcing_cosine"][()], sine=sc["forcing_sine"][()],
                                  constant=sc["forcing_constant"][()], stops=stops, x0=bi["x"][i], v0=bi["v"][i],
                                  t0=t0)
    T = 2 * np.pi / omega
    m, pos, side = stops[j]["mass"], stops[j]["position"], stops[j]["side"]
    gap = lambda x: (x[:, m] - pos) if side == "lower" else (pos - x[:, m])   # ≥ 0 away from the stop
    rate = lambda v: v[:, m] if side == "lower" else -v[:, m]                  # the gap's rate
    # Two periods, so that the flight open at the end of the first (the orbit is periodic) ends.
    r = vibro.simulate(s, transient_periods=0, periods=2, samples=400, events=True, threads=1)
    on_stop = np.asarray(r.events.stop) == j
    et, ek = np.asarray(r.events.t)[on_stop], np.asarray(r.events.kind)[on_stop]   # kinds: impact, stick, release, chatter-limit
    flights = [(et[k], et[k + 1]) for k in range(len(et) - 1) if et[k] < t0 + T and ek[k] in (0, 2)]
    if len(et) == 0:
        flights = [(t0, t0 + T)]
    # Per flight: its ends approached geometrically (1e-9 … 1/2 of the flight) and 200 even steps.
    ends = np.geomspace(1e-9, 0.5, 150)
    fractions = np.unique(np.concatenate([ends, 1.0 - ends, np.linspace(0.0, 1.0, 201)[1:-1]]))
    times = np.concatenate([a + (b - a) * fractions for a, b in flights]) if flights else np.array([])
    approach, how = np.inf, "in free flight"
    if len(times):
        rs = vibro.simulate(s, transient_periods=0, periods=2, sample_times=list(times - t0), threads=1)
        d = gap(np.asarray(rs.samples.x)).reshape(len(flights), len(fractions))
        g1 = rate(np.asarray(rs.samples.v)).reshape(len(flights), len(fractions))
        candidates = []
        for k, (a, b) in enumerate(flights):
            q, w = d[k], g1[k]
            # A turn: the gap falls, then rises (beside an impact's event it only falls or only rises,
            # whatever the rounding of its tiny values there).
            inner = [n for n in range(1, len(q) - 1) if w[n - 1] < 0.0 <= w[n + 1] and q[n] <= min(q[n - 1], q[n + 1])]
            candidates += [(q[n], a + (b - a) * fractions[n - 1], a + (b - a) * fractions[n + 1]) for n in inner]
        for _, lo, hi in sorted(candidates)[:3]:
            for _ in range(2):   # twice: the second grid around the first one's least sample
                fine = np.linspace(lo, hi, 4001)
                rr = vibro.simulate(s, transient_periods=0, periods=2, sample_times=list(fine - t0), threads=1)
                q = gap(np.asarray(rr.samples.x))
                n = int(np.argmin(q))
                lo, hi = fine[max(n - 1, 0)], fine[min(n + 1, len(fine) - 1)]
            approach = min(approach, float(q[n]))
    r1 = vibro.simulate(s, transient_periods=0, periods=1, samples=20000, events=True, threads=1)
    t = np.asarray(r1.samples.t)
    impacts = (np.asarray(r1.events.stop) == j) & (np.asarray(r1.events.kind) == 0)  # kind 0: impact
    it, speeds = np.asarray(r1.events.t)[impacts], np.abs(np.asarray(r1.events.v_before)[impacts])
    if len(it):
        e = int(np.argmin(speeds))
        # |g''| before the slowest impact from the samples of the mass's velocity just before it.
        before = (t < it[e]) & (t > it[e] - 2e-3 * T)
        if np.count_nonzero(before) >= 3:
            vm = np.asarray(r1.samples.v)[before, m]
            acc = abs(np.polyfit(t[before], vm, 1)[0])
            if acc > 0 and speeds[e] ** 2 / (2 * acc) < approach:
                approach = speeds[e] ** 2 / (2 * acc)
                how = f"as a touch (an impact at speed {speeds[e]:.1e} whose free path would pass the stop by that much)"
    if not np.isfinite(approach):
        c.fail("no touch in free flight and no impact on the stop: nothing to measure")
    return approach, abs(pos), how


def a1_of(f):
    return float(f["scene/forcing_cosine"][0])


def main():
    vibro = None
    if len(sys.argv) > 2 and sys.argv[1] == "--build":
        build = sys.argv[2]
        del sys.argv[1:3]
        sys.path.insert(0, os.path.join(build, "python"))
        try:
            import vibro
        except ImportError as e:
            c.fail(f"the vibro Python module is not in {build}/python ({e}): build first")
    inputs, outdir = c.args(1, 64, "[--build BUILD_DIR] CURVE.h5 [CURVE2.h5 …] [CHECK.h5 …] OUTDIR")

    def check_grazing_orbit(f, i, where):
        if vibro is None:
            return
        gap, scale, how = nearest_approach(vibro, f, i)
        print(f"  {where}: the grazing orbit at Omega = {f['bifurcations/p'][i]:.10f} comes within {gap:.1e} of the stop "
              f"{how} (run for one period from its state)")
        if gap > 1e-9 * scale:
            failures.append(f"{where}: the located grazing orbit at Omega = {f['bifurcations/p'][i]:.10f} stays {gap:.1e} away "
                   f"from its stop: not a grazing")
    curves, checks = [], []
    failures = []  # checks that do not hold: all reported, the figure drawn, then a non-zero exit
    for path in inputs:
        with h5py.File(path, "r") as f:
            kind = "curve" if "curve" in f else "locate" if "transitions" in f else "continue" if "bifurcations" in f else None
        if kind is None:
            c.fail(f"{path}: neither a curve, a locate nor a continuation file")
        if kind == "curve":
            curves += read_curves(path)
        else:
            checks.append((kind, path))
    if not curves:
        c.fail("no curve file given")
    for path in inputs:
        with h5py.File(path, "r") as f:
            if "curve" in f:
                names = [text(n) for n in f["bifurcations/kind"].attrs["names"]]
                for i in range(len(f["bifurcations/p"])):
                    if names[int(f["bifurcations/kind"][i])] == "grazing" and f["bifurcations/smooth"][i] \
                            and int(f["bifurcations/stop"][i]) == 0:
                        check_grazing_orbit(f, i, f"{path} (the curve's start)")
    for cv in curves:
        print(f"curve of the {cv['kind']} of stop {cv['stop']} ({cv['file']}): {len(cv['p1'])} points, "
              f"Omega {cv['p1'].min():.7f} .. {cv['p1'].max():.7f}, A1 {cv['p2'].min():.6f} .. {cv['p2'].max():.6f}; "
              f"largest |test| {np.max(np.abs(cv['value'])):.1e}; ends: {cv['end']}")

    # ---- the checks
    rows = []   # (A1, Omega_curve, Omega_check, kind, how, bracket)
    for how, path in checks:
        with h5py.File(path, "r") as f:
            c.check_status(f, path) if how == "continue" else None
            a1 = a1_of(f)
            if how == "locate":
                tr = {k: f["transitions"][k][()] for k in f["transitions"]}
                names = [text(n) for n in f["transitions/kind"].attrs["names"]]
                found = [(float(tr["parameter"][i]), float(tr["parameter_low"][i]), float(tr["parameter_high"][i]), "rising", i)
                         for i in range(len(tr["kind"])) if names[int(tr["kind"][i])] == "rising" and int(tr["stop"][i]) == 0]
            else:
                bi = {k: f["bifurcations"][k][()] for k in f["bifurcations"]}
                names = [text(n) for n in f["bifurcations/kind"].attrs["names"]]
                found = [(float(bi["p"][i]), float(bi["p_low"][i]), float(bi["p_high"][i]), names[int(bi["kind"][i])], i)
                         for i in range(len(bi["kind"]))
                         if names[int(bi["kind"][i])] in ("rising", "grazing") and int(bi["stop"][i]) == 0 and bi["smooth"][i]]
        # the curve point with this A1
        match = [(cv, j) for cv in curves for j in range(len(cv["p2"])) if abs(cv["p2"][j] - a1) <= 1e-12 * max(1.0, abs(a1))]
        if not match:
            c.fail(f"{path}: A1 = {a1!r} is not the A1 of a curve point")
        cv, j = match[0]
        target = float(cv["p1"][j])
        cands = [x for x in found if x[3] == cv["kind"]]
        if not cands:
            failures.append(f"{path} ({how} at A1 = {a1:.9f}): no {cv['kind']} of s1 located by a smooth condition "
                            f"(the curve has it at Omega = {target:.10f})")
            print(f"check ({how:8s}) {cv['kind']} of s1 at A1 = {a1:.9f}: curve Omega = {target:.10f}, {how}: none located")
            continue
        p, lo, hi, _, idx = min(cands, key=lambda x: abs(x[0] - target))
        diff = p - target
        if how == "locate":
            width = hi - lo
            ok = lo - width - LOCATE_MARGIN <= target <= hi + width + LOCATE_MARGIN
            inside = lo <= target <= hi
            note = f"bracket [{lo:.10f}, {hi:.10f}] (width {width:.1e}): the curve's Omega {'inside' if inside else 'outside'}"
        else:
            width = 0.0
            ok = abs(diff) <= CONTINUE_TOL
            note = f"tolerance {CONTINUE_TOL:.0e}"
        print(f"check ({how:8s}) {cv['kind']} of s1 at A1 = {a1:.9f}: curve Omega = {target:.10f}, "
              f"{how} Omega = {p:.10f}, difference {diff:+.1e}; {note}")
        if how == "continue" and cv["kind"] == "grazing":
            with h5py.File(path, "r") as f:
                check_grazing_orbit(f, idx, path)
        if not ok:
            failures.append(f"{path}: the {how} run's {cv['kind']} at Omega = {p:.10f} is {diff:+.1e} from the curve point {target:.10f}")
        rows.append((a1, target, p, cv["kind"], how, width))
    if not checks:
        print("no check files given: the curves are drawn unchecked")

    # ---- the figure
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.6), gridspec_kw={"width_ratios": [1.6, 1]})
    labelled = set()
    for cv in curves:
        key = (cv["kind"], cv["stop"])
        col = COLOURS.get(key, "k")
        order = np.argsort(cv["p2"])
        lab = None if key in labelled else f"{cv['kind']} of mass {cv['stop'] + 1} (stop s{cv['stop'] + 1})"
        labelled.add(key)
        ax.plot(cv["p1"], cv["p2"], "-", color=col, lw=1.3, label=lab)
        ax.plot(cv["p1"], cv["p2"], "o", color=col, ms=2.5)
        # the curve's far end, with why it stopped
        end = "lost" if "lost" in cv["end"] else "limits" if "limits" in cv["end"] else "no orbit" if "no orbit" in cv["end"] else cv["end"][:20]
        ax.annotate(end, (cv["p1"][-1], cv["p2"][-1]), textcoords="offset points", xytext=(4, -8), fontsize=7, color=col)
    ax.axhline(PAPER_A1, color="grey", lw=0.7, ls=":", label="A1 = 0.5: the paper's scan in Ω")
    ax.plot([PAPER_RISING], [PAPER_A1], "*", color="k", ms=10, label=f"the paper's rising, Ω = {PAPER_RISING}")
    for a1, target, p, kind, how, width in rows:
        ax.plot([target], [a1], "o", ms=8 if how == "locate" else 11, mfc="none",
                mec="tab:red" if how == "locate" else "tab:purple", mew=0.9)
    if rows:
        ax.plot([], [], "o", ms=8, mfc="none", mec="tab:red", label="checked by locate at fixed A1")
        ax.plot([], [], "o", ms=11, mfc="none", mec="tab:purple", label="checked by continue in Ω at fixed A1")
    ax.set(xlabel="Ω", ylabel="$A_1$ (forcing amplitude on mass 1)",
           title="(a) rising and grazing of mass 1 in (Ω, $A_1$)")
    ax.ticklabel_format(axis="x", useOffset=False)
    ax.legend(loc="upper left", fontsize=7)
    if rows:
        for how, mk, col in (("locate", "o", "tab:red"), ("continue", "s", "tab:purple")):
            sel = [r for r in rows if r[4] == how]
            if not sel:
                continue
            a = np.array([r[0] for r in sel])
            d = np.maximum(np.abs(np.array([r[2] - r[1] for r in sel])), 1e-17)
            bx.semilogy(a, d, mk, color=col, ls="none", label=f"|Ω({how}) − Ω(curve)|")
            if how == "locate":
                bx.semilogy(a, [r[5] for r in sel], "_", color=col, ms=14, mew=1.5, label="locate's bracket width")
        bx.set(xlabel="$A_1$", ylabel="difference in Ω", title="(b) the curve points checked at fixed $A_1$")
        bx.legend(loc="center right", fontsize=7)
    else:
        bx.axis("off")
    fig.tight_layout()
    print(f"figure: {c.save(fig, outdir, 'two_parameter')}")
    for msg in failures:
        print(f"CHECK FAILED: {msg}")
    if failures:
        sys.exit(f"two_parameter: {len(failures)} check(s) failed (above)")


if __name__ == "__main__":
    main()

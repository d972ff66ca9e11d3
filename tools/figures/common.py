"""Reading helpers shared by the figure scripts of Wagg (2004), "Rising phenomena and the
multi-sliding bifurcation in a two-degree of freedom impact oscillator", Chaos, Solitons and
Fractals 22 (2004) 541-548 (figs. 2-6).

Result files follow docs/results.md (simulations and sweeps) and framework/io/src/locate.cpp
(`run.kind: locate`: groups /scan, /phases, /transitions). Masses are numbered from 0 in the
files; the paper numbers them from 1, so the paper's x1 is our x[:, 0] and its x2 our x[:, 1].

Every script is run as   python3 tools/figures/<script>.py IN.h5 [IN2.h5] OUTDIR
and writes OUTDIR/<name>.png and OUTDIR/<name>.pdf with matplotlib's Agg backend.
"""

import os
import sys
from dataclasses import dataclass, field

import matplotlib

matplotlib.use("Agg")
import h5py  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

# Periodicity: z(t + kT) = z(t) to this fraction of the orbit's amplitude (max |x|, max |v|).
# The same 1e-10 as the locate runs' `periodicity` (experiments/wagg2004/rising_scan.yaml).
PERIODICITY_TOL = 1e-10
MAX_PERIOD = 8

# One colour per stop, and the paper's line styles: x1 broken, x2 solid.
STOP_COLOURS = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown"]
MASS_STYLES = ["--", "-", ":", "-."]
MASS_COLOURS = ["tab:blue", "black", "tab:green", "tab:red"]

plt.rcParams.update({"font.size": 9, "axes.titlesize": 9, "legend.fontsize": 8,
                     "savefig.dpi": 150, "figure.dpi": 150})


def vibro_module():
    """The `vibro` Python module (its plotting helpers, vibro.plot, draw the standard figures):
    from PYTHONPATH, else from the build folder VIBRO_BUILD (default build/release) of this
    checkout."""
    try:
        import vibro.plot
        return vibro
    except ImportError:
        pass
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    sys.path.insert(0, os.path.join(root, os.environ.get("VIBRO_BUILD", "build/release"), "python"))
    try:
        import vibro.plot
    except ImportError as e:
        fail(f"cannot import the vibro module ({e}): build it (cmake --build --preset release) or set PYTHONPATH")
    return vibro


def fail(message):
    """Stop the script loudly: a figure drawn from data that do not check out is worse than none."""
    sys.stderr.write(f"error: {message}\n")
    sys.exit(1)


def args(n_inputs_min, n_inputs_max, usage):
    """IN.h5 [IN2.h5 …] OUTDIR from the command line; OUTDIR is created."""
    a = sys.argv[1:]
    if not (n_inputs_min + 1 <= len(a) <= n_inputs_max + 1):
        fail(f"usage: {os.path.basename(sys.argv[0])} {usage}")
    for path in a[:-1]:
        if not os.path.isfile(path):
            fail(f"{path}: no such file")
    os.makedirs(a[-1], exist_ok=True)
    return a[:-1], a[-1]


def save(fig, outdir, name):
    for ext in ("png", "pdf"):
        fig.savefig(os.path.join(outdir, f"{name}.{ext}"), bbox_inches="tight")
    plt.close(fig)
    return os.path.join(outdir, f"{name}.png")


def mass_label(i):
    """The paper's symbol for mass i (numbered from 0 in files, from 1 in the paper)."""
    return f"$x_{i + 1}$"


def velocity_label(i):
    return f"$\\dot x_{i + 1}$"


# ----------------------------------------------------------------------------------- scene


@dataclass
class Scene:
    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    F0: np.ndarray
    Fc: np.ndarray
    Fs: np.ndarray
    omega: float
    period: float
    stop_kind: list          # 'upper', 'lower', 'between'
    stop_mass: np.ndarray
    stop_other: np.ndarray
    stop_position: np.ndarray
    stop_amplitude: np.ndarray
    stop_name: list
    name: str = ""
    run_kind: str = ""

    @property
    def n(self):
        return self.M.shape[0]

    @property
    def m(self):
        return len(self.stop_name)

    def forcing(self, t, omega=None):
        """f(t) = F0 + Fc cos Ωt + Fs sin Ωt, shape (len(t), n)."""
        w = self.omega if omega is None else omega
        t = np.atleast_1d(t)[:, None]
        return self.F0[None, :] + self.Fc[None, :] * np.cos(w * t) + self.Fs[None, :] * np.sin(w * t)

    def stop_label(self, j):
        """'s1 (mass 0, lower)': the stop's name, the mass (numbered from 0) and its side."""
        if self.stop_kind[j] == "between":
            return f"{self.stop_name[j]} ($x_{self.stop_mass[j] + 1}-x_{self.stop_other[j] + 1}$)"
        return f"{self.stop_name[j]} (on {mass_label(self.stop_mass[j])}, {self.stop_kind[j]})"


def read_scene(f):
    s = f["scene"]
    a = s.attrs
    kinds = list(s["stop_kind"].attrs["names"])
    if "mass" in s:
        M, C, K = s["mass"][()], s["damping"][()], s["stiffness"][()]
    else:  # modal engine: the chain in banded form (docs/results.md); dense here, for figures
        M = np.diag(s["mass_diagonal"][()])
        off = s["stiffness_off_diagonal"][()]
        K = np.diag(s["stiffness_diagonal"][()]) + np.diag(off, 1) + np.diag(off, -1)
        alpha, beta = s["rayleigh"][()]
        C = alpha * M + beta * K
    return Scene(M=M, C=C, K=K,
                 F0=s["forcing_constant"][()], Fc=s["forcing_cosine"][()], Fs=s["forcing_sine"][()],
                 omega=float(a["frequency"]), period=float(a["period"]),
                 stop_kind=[kinds[k] for k in s["stop_kind"][()]], stop_mass=s["stop_mass"][()],
                 stop_other=s["stop_other"][()], stop_position=s["stop_position"][()],
                 stop_amplitude=s["stop_amplitude"][()],
                 stop_name=list(s["stop_name"].asstr()[()]), name=str(a["name"]),
                 run_kind=str(a["run_kind"]))


def check_status(f, path):
    status = f["meta"].attrs["status"]
    if status != "completed":
        fail(f"{path}: run status '{status}': {f['meta'].attrs.get('message', '')}")


# ------------------------------------------------------------------ simulations and sweeps


@dataclass
class Run:
    """One simulation, or one point of a sweep: its own Ω, samples, Poincaré states, contacts."""
    omega: float
    period: float
    t: np.ndarray            # samples
    x: np.ndarray
    v: np.ndarray
    pt: np.ndarray           # Poincaré section
    px: np.ndarray
    pv: np.ndarray
    contacts: dict = field(default_factory=dict)   # name -> array
    events: dict = field(default_factory=dict)


def _ragged(group, p):
    """Rows of point p of a concatenated group (or the whole group for a simulation)."""
    out = {}
    if "point" in group:
        rows = group["rows"][()]
        start = np.concatenate([[0], np.cumsum(rows)])
        sl = slice(int(start[p]), int(start[p + 1]))
    else:
        sl = slice(None)
    for name in group:
        if name in ("point", "rows"):
            continue
        out[name] = group[name][sl]
    return out


def _stacked(group, name, p, sweep):
    if not sweep:
        return group[name][()]
    r = int(group["rows"][p])
    return group[name][p, :r]


def read_runs(path, scene_needed=True):
    """All runs of a simulate or sweep file: (scene, [Run, …]). Needs /samples and /poincare."""
    with h5py.File(path, "r") as f:
        check_status(f, path)
        scene = read_scene(f)
        sweep = "sweep" in f
        if "samples" not in f or "poincare" not in f:
            fail(f"{path}: needs record.samples and record.poincare")
        runs = []
        points = int(f["sweep"].attrs["points"]) if sweep else 1
        if sweep:
            params = list(f["sweep"].attrs["parameters"])
            if "forcing.frequency" not in params:
                fail(f"{path}: the sweep does not vary forcing.frequency ({params})")
            col = params.index("forcing.frequency")
            if np.any(f["sweep/status"][()] != 0):
                fail(f"{path}: sweep points stopped early: status {f['sweep/status'][()]}")
        for p in range(points):
            omega = float(f["sweep/values"][p, col]) if sweep else scene.omega
            run = Run(omega=omega, period=2 * np.pi / omega,
                      t=_stacked(f["samples"], "t", p, sweep), x=_stacked(f["samples"], "x", p, sweep),
                      v=_stacked(f["samples"], "v", p, sweep), pt=_stacked(f["poincare"], "t", p, sweep),
                      px=_stacked(f["poincare"], "x", p, sweep), pv=_stacked(f["poincare"], "v", p, sweep))
            if "contacts" in f:
                run.contacts = _ragged(f["contacts"], p)
            if "events" in f:
                run.events = _ragged(f["events"], p)
            runs.append(run)
    return scene, runs


@dataclass
class Periodicity:
    k: int                   # least period in forcing periods, 0 if none
    residual: float          # residual of that k (or the least residual found)
    k_max_checked: int

    @property
    def periodic(self):
        return self.k > 0

    def text(self):
        if self.periodic:
            return f"periodic, k = {self.k}, residual {self.residual:.0e}"
        return f"NOT periodic within the run (k <= {self.k_max_checked}: least residual {self.residual:.0e})"

    def colour(self):
        return "black" if self.periodic else "red"


def periodicity(run, tol=PERIODICITY_TOL, max_k=MAX_PERIOD):
    """The least k <= max_k with max_n |z_n - z_{n-k}| <= tol over the Poincaré states z_n = (x, v),
    each coordinate relative to the orbit's amplitude (max |x| and max |v| over the samples)."""
    xs = max(np.max(np.abs(run.x)), np.finfo(float).tiny)
    vs = max(np.max(np.abs(run.v)), np.finfo(float).tiny)
    z = np.hstack([run.px / xs, run.pv / vs])
    if not np.all(np.isfinite(z)):
        fail("non-finite Poincaré state")
    k_max = min(max_k, len(z) - 1)
    best = np.inf
    for k in range(1, k_max + 1):
        r = float(np.max(np.abs(z[k:] - z[:-k])))
        if r <= tol:
            return Periodicity(k, r, k_max)
        best = min(best, r)
    return Periodicity(0, best, k_max)


def sticking_intervals(run, stop):
    """[(t_start, t_end), …] of one stop, from /contacts."""
    c = run.contacts
    if not c:
        fail("the file has no /contacts (record.contacts: true is needed)")
    sel = c["stop"] == stop
    return list(zip(c["t_start"][sel], c["t_end"][sel]))


def sticking_fractions(run, scene):
    """Fraction of the recorded span each stop holds (from /contacts), per stop."""
    span = run.t[-1] + (run.t[1] - run.t[0]) - run.t[0]
    return [sum(b - a for a, b in sticking_intervals(run, j)) / span for j in range(scene.m)]


def shade_sticking(ax, run, scene, t_offset=0.0, label=True):
    for j in range(scene.m):
        for i, (a, b) in enumerate(sticking_intervals(run, j)):
            ax.axvspan(a - t_offset, b - t_offset, color=STOP_COLOURS[j % len(STOP_COLOURS)], alpha=0.18,
                       lw=0, label=f"{scene.stop_name[j]} holds" if (label and i == 0) else None)


def draw_stops(ax, scene, label=True):
    """Fixed stops as horizontal lines at their positions."""
    for j in range(scene.m):
        if scene.stop_kind[j] == "between":
            continue
        ax.axhline(scene.stop_position[j], color=STOP_COLOURS[j % len(STOP_COLOURS)], lw=1.2,
                   label=(f"stop {scene.stop_name[j]}: {mass_label(scene.stop_mass[j])} "
                          f"{'≥' if scene.stop_kind[j] == 'lower' else '≤'} {scene.stop_position[j]:g}")
                   if label else None)


# --------------------------------------------------------------------------- locate files


@dataclass
class Locate:
    scene: Scene
    parameter_path: str
    p: np.ndarray
    periodic: np.ndarray
    k: np.ndarray
    sticking: np.ndarray      # P×m
    phases: dict              # point, stop, phase, duration, force_min, …
    transitions: dict         # kind, stop, parameter, …, kind_names


def read_locate(path):
    with h5py.File(path, "r") as f:
        if "scan" not in f or "phases" not in f or "transitions" not in f:
            fail(f"{path}: not a locate file (needs /scan, /phases, /transitions)")
        status = f["meta"].attrs["status"]
        if status != "completed":
            sys.stderr.write(f"warning: {path}: status '{status}': {f['meta'].attrs.get('message', '')}\n")
        scene = read_scene(f)
        s = f["scan"]
        tr = {n: f["transitions"][n][()] for n in f["transitions"]}
        tr["kind_names"] = list(f["transitions/kind"].attrs["names"])
        return Locate(scene=scene, parameter_path=str(s.attrs["parameter"]), p=s["parameter"][()],
                      periodic=s["periodic"][()], k=s["k"][()], sticking=s["sticking_fraction"][()],
                      phases={n: f["phases"][n][()] for n in f["phases"]}, transitions=tr)


def phase_parts(loc, stop, max_parts=4):
    """Per scan point, the durations (fractions of T) of the stop's sticking phases in the first
    forcing period of the orbit, in order of their phase within the period: array P×max_parts, NaN
    where a point has fewer phases. (/phases/phase is in units of T from the orbit's start, so a
    k-periodic orbit, k > 1, lists its phases of periods 2 … k with phase >= 1; they are left out.)
    Also returns the most parts any point has."""
    P = len(loc.p)
    out = np.full((P, max_parts), np.nan)
    most = 0
    ph = loc.phases
    for i in range(P):
        sel = (ph["point"] == i) & (ph["stop"] == stop) & (ph["phase"] < 1.0)
        order = np.argsort(ph["phase"][sel])
        d = ph["duration"][sel][order]
        most = max(most, len(d))
        out[i, :min(len(d), max_parts)] = d[:max_parts]
    return out, most


def draw_transitions(ax, loc, y_top=None):
    """Located transitions as dotted vertical lines, numbered at the top (transitions closer than
    1.5 % of the range share one label); returns the key lines '1: rising s1  Ω = …'."""
    sc, tr = loc.scene, loc.transitions
    lo, hi = loc.p.min(), loc.p.max()
    span = hi - lo
    y = ax.get_ylim()[1] if y_top is None else y_top
    key, group, last = [], [], None
    order = [k for k in np.argsort(tr["parameter"]) if lo <= tr["parameter"][k] <= hi]

    def flush():
        if group:
            ax.text(np.mean([g[1] for g in group]), y, ",".join(str(g[0]) for g in group), ha="center",
                    va="bottom", fontsize=7, color=group[0][2])

    for num, k in enumerate(order, start=1):
        pv = tr["parameter"][k]
        s = int(tr["stop"][k])
        col = STOP_COLOURS[s % len(STOP_COLOURS)] if s >= 0 else "gray"
        ax.axvline(pv, color=col, ls=":", lw=1.0)
        if last is not None and pv - last > 0.015 * span:
            flush()
            group = []
        group.append((num, pv, col))
        last = pv
        name = sc.stop_name[s] if s >= 0 else "(orbit)"
        key.append(f"{num}: {tr['kind_names'][int(tr['kind'][k])]} {name}  "
                   f"{parameter_symbol(loc.parameter_path).strip('$').replace(chr(92) + 'Omega', 'Ω')} = {pv:.10f}")
    flush()
    return key


def parameter_symbol(path):
    return "$\\Omega$" if path == "forcing.frequency" else path


def draw_sticking_vs_parameter(ax, loc, stops=None, show_transitions=False):
    """Sticking fraction per stop (total, line) and its parts (markers) vs the parameter; located
    non-periodic points as red crosses, k-periodic ones (k > 1) ringed. Transitions: draw_transitions."""
    sc = loc.scene
    stops = range(sc.m) if stops is None else stops
    markers = ["o", "s", "^", "v"]
    for j in stops:
        col = STOP_COLOURS[j % len(STOP_COLOURS)]
        ax.plot(loc.p, loc.sticking[:, j], "-", color=col, lw=0.8, alpha=0.6,
                label=f"{sc.stop_name[j]} on {mass_label(sc.stop_mass[j])}: total")
        parts, most = phase_parts(loc, j)
        for q in range(min(most, parts.shape[1])):
            lab = f"{sc.stop_name[j]}: part {q + 1}" if most > 1 else f"{sc.stop_name[j]}: sticking phase"
            ax.plot(loc.p, parts[:, q], markers[q], ms=2.6 if q == 0 else 3.2, color=col,
                    mfc=col if q == 0 else "white", mew=0.8, ls="none", label=lab)
    multi = (loc.periodic != 0) & (loc.k > 1)
    if np.any(multi):
        for j in stops:
            ax.plot(loc.p[multi], loc.sticking[multi, j], "o", ms=8, mfc="none", mec="black", mew=0.8,
                    label="period $k > 1$ (phases of its 1st period)" if j == list(stops)[0] else None)
    bad = loc.periodic == 0
    if np.any(bad):
        for j in stops:
            ax.plot(loc.p[bad], loc.sticking[bad, j], "x", color="red", ms=6, mew=1.4,
                    label="not periodic" if j == list(stops)[0] else None)
    if show_transitions:
        draw_transitions(ax, loc)
    ax.set_xlabel(parameter_symbol(loc.parameter_path))
    ax.set_ylabel("sticking time / forcing period $T$")

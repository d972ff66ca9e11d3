"""vibro — exact, event-driven simulation of vibro-impact systems, from Python.

The C++ framework of this repository with numpy in and out: a scene (a YAML file, YAML text, or
numpy matrices and a list of stops) is run by the same engine and the same code as the command
``vibro run``; the result holds what the HDF5 file of ``vibro run`` holds, under the same names
(docs/results.md), as numpy arrays, and ``result.save(path)`` writes that file.

    import vibro
    scene = vibro.Scene.load("experiments/wagg2004/fig2_sticking_orbit.yaml")
    scene.set("forcing.frequency", 0.2561)              # the paths of `vibro run --set`
    result = vibro.simulate(scene, periods=4)           # GIL released; Ctrl-C stops it
    t, x = result.samples.t, result.samples.x            # (r,), (r, n) numpy arrays
    result.save("fig4c.h5")                               # the file `vibro run` writes

Functions: one per run kind of the table ``vibro run`` dispatches on (``run_kinds()``):
simulate, sweep, locate, continuation (run.kind: continue), basin, diagram, lyapunov, orbit —
each takes a scene (a Scene, a file path or YAML text) and keyword overrides of its run section,
optionally writes the result file (``output=``), shows its progress (``progress=True`` or a
callable) and returns a Result; run (whatever the scene's run.kind says) and read (a result
file). One orbit at a time, on the dense engine: shoot
(Newton shooting), tangent_map (the exact linearisation over a span) and multipliers (of a
state's k-period map). Classes: Scene, Result, Group. Errors: SceneError (a ValueError: the
command's message, 'file:line:column: key.path: problem'), ResultError (an OSError), Interrupted
(a KeyboardInterrupt carrying the partial result). Guide and reference: docs/python.md.
"""
import json
import math
import os
import sys
import types
import warnings

import numpy as np

from ._vibro import ResultError, SceneError, __version__
from ._vibro import Image as _Image
from ._vibro import SceneDocument as _Document
from ._vibro import run_kinds as _run_kinds

# Completed below with the function of every run kind (one per entry of run_kinds()).
__all__ = ["Scene", "Result", "Group", "run", "read", "run_kinds", "run_function", "shoot", "tangent_map",
           "multipliers", "SceneError", "ResultError", "Interrupted", "__version__"]

_OBSERVERS = ("events", "contacts", "statistics", "poincare", "impact_map")


class Interrupted(KeyboardInterrupt):
    """A run stopped by Ctrl-C (a KeyboardInterrupt raised by Python's signal handler).

    ``result`` is what was computed until then: a simulation up to the event where it stopped
    (status ``interrupted``), a sweep's finished points (``/sweep`` attribute ``completed``), a
    locate run with the orbits it had; None when the interrupt came during a set-up before the
    run held anything (the modes of a long modal chain, a large system's factorisations: they
    run where the stop is answered within 10 ms, docs/results.md "Signals"). Catch
    ``KeyboardInterrupt`` to keep it::

        try:
            r = vibro.sweep(scene, {"forcing.frequency": np.linspace(0.24, 0.28, 400)})
        except KeyboardInterrupt as stop:
            r = stop.result
    """

    def __init__(self, message, result):
        super().__init__(message)
        self.result = result


# --- Scenes --------------------------------------------------------------------------------------

class Scene:
    """A validated scene: what `vibro run` reads from a YAML file (docs/scenes.md).

    Make one with ``Scene.load(path)``, ``Scene.from_text(text)`` or ``Scene.from_matrices(M, C,
    K, ...)``. Every number of the scene is addressed by the paths of ``vibro run --set``:
    ``scene.get("forcing.frequency")``, ``scene.set("stops[1].position", 0.12)``. Each change is
    validated at once, with the command's messages; an invalid change raises SceneError and leaves
    the scene as it was. A scene is never changed by running it: the run functions' keyword
    arguments apply to that run only.

    Properties (resolved, as `vibro check` prints them): ``dof``, ``stops`` (names), ``frequency``,
    ``period``, ``t0``, ``x0``, ``v0``, ``engine``, ``run_kind``, ``periods``,
    ``transient_periods``, ``record`` (dict), ``axes`` (swept or scanned paths and values),
    ``name``, ``file``, ``yaml`` (the text as loaded).
    """

    def __init__(self, document):
        """Wraps a compiled scene document and validates it (use the class methods instead)."""
        self._doc = document
        self._resolved = document.check()

    @classmethod
    def load(cls, path):
        """Reads and validates a scene file. Raises SceneError ('file:line:column: path: problem')."""
        return cls(_Document.load(str(path)))

    @classmethod
    def from_text(cls, text, file="<string>"):
        """Parses and validates scene text (YAML); ``file`` names it in error messages."""
        return cls(_Document.parse(text, file))

    @classmethod
    def from_matrices(cls, M, C=None, K=None, *, frequency=0.0, cosine=None, sine=None, constant=None,
                      stops=(), x0=None, v0=None, t0=None, solver=None, record=None, run=None, name=None):
        """A scene from numpy: M x'' + C x' + K x = constant + cosine cos(Ωt) + sine sin(Ωt).

        M, C, K: n × n arrays (C and K default to zero); frequency: Ω ≥ 0 [rad per unit time];
        cosine, sine, constant: length-n force amplitudes (default zero). stops: a list of dicts
        with the keys of a scene file's stops (docs/scenes.md), e.g. ``{"mass": 0, "side":
        "lower", "position": -0.3, "restitution": 0.7, "name": "s1"}`` or ``{"between": [1, 2],
        "gap": 0.05, "restitution": 0.8}``. x0, v0, t0: the initial state (default rest at 0,
        t = 0). solver, record, run: dicts with the keys of those sections, e.g. ``record={"events":
        True, "samples": {"per_period": 100}}``, ``run={"transient_periods": 200, "periods": 4}``.

        Arrays are checked here (shape, finite entries: ValueError naming the argument and the
        entry); everything else — symmetry and definiteness of M, C, K, the stops, the initial
        state — by the scene loader, with its messages (SceneError, a ValueError). The scene's
        text is generated (``scene.yaml``: the numbers written to round trip exactly), so its
        paths are those of a file with ``model.matrices``: ``model.matrices.mass[0][1]``.
        """
        mass = _matrix("M", M)
        n = mass.shape[0]
        damping = np.zeros((n, n)) if C is None else _matrix("C", C, n)
        stiffness = np.zeros((n, n)) if K is None else _matrix("K", K, n)
        lines = ["# A scene built by vibro.Scene.from_matrices (Python)."]
        if name is not None:
            lines.append("name: " + json.dumps(str(name)))
        lines += ["model:", "  matrices:"]
        for key, matrix in (("mass", mass), ("damping", damping), ("stiffness", stiffness)):
            lines.append(f"    {key}:")
            lines += ["      - " + _flow(row) for row in matrix]
        lines += ["forcing:", "  frequency: " + _number("frequency", frequency)]
        for key, vector in (("constant", constant), ("cosine", cosine), ("sine", sine)):
            if vector is not None:
                lines.append(f"  {key}: " + _flow(_vector(key, vector, n)))
        if stops:
            lines.append("stops:")
            lines += ["  - " + json.dumps(_plain(stop, f"stops[{j}]")) for j, stop in enumerate(stops)]
        initial = [("time", None if t0 is None else _number("t0", t0)),
                   ("x", None if x0 is None else _flow(_vector("x0", x0, n))),
                   ("v", None if v0 is None else _flow(_vector("v0", v0, n)))]
        if any(value is not None for _, value in initial):
            lines.append("initial:")
            lines += [f"  {key}: {value}" for key, value in initial if value is not None]
        for key, section in (("solver", solver), ("record", record), ("run", run)):
            if section is not None:
                lines.append(f"{key}: " + json.dumps(_plain(section, key)))
        return cls.from_text("\n".join(lines) + "\n", "<numpy>")

    # Paths.

    def get(self, path):
        """The number at a scene path, e.g. ``scene.get("stops[0].position")``."""
        return self._doc.get(path)

    def set(self, path, value):
        """Sets the number at a path (as ``vibro run --set PATH=VALUE``) and validates the scene.

        Raises SceneError with the command's message if the path names no number of the scene or
        the new value makes the scene invalid; the scene is then unchanged.
        """
        self.update({path: value})

    def update(self, values):
        """Sets several paths at once (a dict {path: value}), then validates; all or nothing."""
        doc = self._doc.copy()
        for path, value in values.items():
            try:
                number = repr(float(value))  # nan and inf too: refused with the command's message
            except (TypeError, ValueError):
                raise ValueError(f"{path}: expected a number, found {value!r}") from None
            doc.set_assignment(f"{path}={number}")
        resolved = doc.check()
        self._doc, self._resolved = doc, resolved

    def copy(self):
        """An independent copy."""
        return Scene(self._doc.copy())

    # What the scene resolved to.

    yaml = property(lambda self: self._doc.text, doc="The scene's text, as loaded or generated.")
    file = property(lambda self: self._doc.file, doc="The file it was read from ('<string>', '<numpy>').")
    name = property(lambda self: self._resolved["name"], doc="The scene's name: (may be empty).")
    dof = property(lambda self: self._resolved["dof"], doc="Degrees of freedom n.")
    stops = property(lambda self: list(self._resolved["stops"]), doc="Stop names, in order.")
    frequency = property(lambda self: self._resolved["frequency"], doc="Forcing frequency Ω.")
    period = property(lambda self: self._resolved["period"], doc="2π/Ω, or 1 when Ω = 0.")
    t0 = property(lambda self: self._resolved["t0"], doc="Initial time.")
    x0 = property(lambda self: np.array(self._resolved["x0"]), doc="Initial displacements.")
    v0 = property(lambda self: np.array(self._resolved["v0"]), doc="Initial velocities.")
    engine = property(lambda self: self._resolved["engine"], doc="'dense' or 'modal' (solver.engine).")
    run_kind = property(lambda self: self._resolved["run_kind"], doc="'simulate', 'sweep' or 'locate'.")
    frame = property(lambda self: self._resolved["frame"],
                     doc="A base-excited scene's frame of its results (record.frame; default base.frame): "
                         "'absolute' or 'relative'; None without a base.")
    periods = property(lambda self: self._resolved["periods"], doc="Recorded forcing periods.")
    transient_periods = property(lambda self: self._resolved["transient_periods"],
                                 doc="Forcing periods run before recording.")
    record = property(lambda self: dict(self._resolved["record"]), doc="What a run records (record:).")
    axes = property(lambda self: [(p, np.array(v)) for p, v in self._resolved["axes"]],
                    doc="The swept (or scanned) paths and their values.")

    def __repr__(self):
        return (f"<vibro.Scene {self.file!r}{' ' + repr(self.name) if self.name else ''}: {self.dof} DOF, "
                f"stops {self.stops}, Ω = {self.frequency:g}, {self.engine} engine, run {self.run_kind}>")


def _matrix(name, value, n=None):
    a = _array(name, value)
    if a.ndim != 2 or a.shape[0] != a.shape[1] or a.shape[0] == 0:
        raise ValueError(f"{name}: expected a square n × n matrix, got an array of shape {a.shape}")
    if n is not None and a.shape != (n, n):
        raise ValueError(f"{name}: expected shape ({n}, {n}) like M, got {a.shape}")
    return a


def _vector(name, value, n):
    a = _array(name, value)
    if a.shape != (n,):
        raise ValueError(f"{name}: expected {n} entries (one per degree of freedom), got an array of shape {a.shape}")
    return a


# numpy's warning for a complex array converted to float (it drops the imaginary part).
_COMPLEX_WARNING = getattr(getattr(np, "exceptions", np), "ComplexWarning")


def _array(name, value):
    if np.iscomplexobj(value):
        raise ValueError(f"{name}: expected real numbers, found a complex array")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", _COMPLEX_WARNING)
            a = np.asarray(value, dtype=float)
    except _COMPLEX_WARNING:
        raise ValueError(f"{name}: expected real numbers, found complex ones") from None
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: expected an array of numbers ({e})") from None
    bad = np.argwhere(~np.isfinite(a))
    if len(bad):
        where = tuple(int(i) for i in bad[0])
        raise ValueError(f"{name}{list(where)}: expected a finite number, found {a[where]!r}")
    return a


def _values(name, values):
    """A grid of values (a sweep's, a scan's, sample times) as a list of floats: a number or a
    1-D sequence. A 2-D array is refused rather than flattened (its order would be a guess)."""
    a = _array(name, values)
    if a.ndim > 1:
        raise ValueError(f"{name}: expected a 1-D sequence of values, got an array of shape {a.shape}")
    return _plain(list(a.ravel()), name)


def _number(name, value):
    """A number as scene text that reads back to the same double."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number, found {value!r}") from None
    if not math.isfinite(x):
        raise ValueError(f"{name}: expected a finite number, found {x!r}")
    return repr(x)


def _flow(values):
    return "[" + ", ".join(repr(float(v)) for v in values) + "]"


def _plain(value, where):
    """Dicts, lists and numbers (numpy ones too) as JSON-ready Python values (JSON is YAML)."""
    if isinstance(value, dict):
        return {str(k): _plain(v, f"{where}.{k}") for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        if not math.isfinite(value):
            raise ValueError(f"{where}: expected a finite number, found {float(value)!r}")
        return float(value)
    if isinstance(value, str):
        return value
    raise ValueError(f"{where}: expected a number, text, list or mapping, found {value!r}")


# --- Runs ----------------------------------------------------------------------------------------

# Keywords every run function takes (besides its run section's keys).
_COMMON = """
    The scene is a Scene, a scene file's path or YAML text (a str with a line break); it is not
    changed: the keywords apply to this run only, and the run section of the scene's own kind is
    replaced, so a scene written for another run kind runs as this one. output: also write the
    result file there (as ``vibro run -o``; an existing file is replaced only with force=True).
    threads: OpenMP threads (None: all cores), as ``vibro run --threads``. progress: True shows
    the run's progress on stderr as ``vibro run`` does (a redrawn line on a terminal, else a line
    at each tenth of the run); a callable is called as ``progress(done, total)`` from the calling
    thread as the run goes on (grid points, or forcing periods of one long simulation), e.g. to
    move a tqdm bar; an exception it raises stops the run and is raised.

    Returns a Result (the groups of docs/results.md as numpy arrays). Raises SceneError (a
    ValueError: 'file:line:column: key.path: problem', the command's message; for a value given
    as a keyword, 'function(keyword=…): key.path: problem') for a bad scene or keyword. The GIL is
    released while the run goes on; Ctrl-C raises Interrupted, a KeyboardInterrupt whose
    ``result`` holds what was done.
"""

# The Python name of a run kind's function where the kind's own name is a Python keyword.
_FUNCTION_NAMES = {"continue": "continuation"}
# The grid keys of a run section: one of them is given; a keyword naming one replaces the others.
_GRID_KEYS = ("values", "linspace", "logspace")


def simulate(scene, *, periods=None, transient_periods=None, output=None, force=False, threads=None, progress=None,
             **record):
    """Simulates the scene once (run.kind: simulate): transient periods, then recorded ones.

    periods, transient_periods: override run.periods and run.transient_periods for this run.
    Record keywords choose the observers for this run, replacing the scene's choice for each one
    given (only what is recorded is computed):
      events, contacts, statistics, poincare: True or False;
      samples: samples per forcing period (an int ≥ 1, 0 for none), or sample_times: times from
      the start of the recording; section: a hyperplane as record.section (a dict
      {coordinate | normal, value, direction}; None: none); record: a dict, a whole record:
      section to start from instead of the scene's (what it does not list is off), which the
      single keywords then change.
    The Result holds the groups recorded (``result.events.t``, ``result.samples.x``, …) and
    /scene and /meta. ``result.status`` is 'completed', or why the run stopped early
    ('event_cap', 'numerical_failure', 'unsupported'); ValueError for a start the engine refuses.
    """
    scene = _scene_of(scene)
    doc = _prepared(scene, periods, transient_periods, record)
    _only_kind(doc, "simulate")
    return _run(doc, threads, output, force, progress)


def sweep(scene, parameters=None, *, follow=None, reverse=None, periods=None, transient_periods=None,
          output=None, force=False, threads=None, progress=None, **record):
    """Runs the scene at every point of a grid of one or two scene paths, in parallel (run.kind: sweep).

    parameters: ``{path: values}`` with one or two paths (the second varies fastest), e.g.
    ``{"forcing.frequency": np.linspace(0.24, 0.28, 81)}``; None: the scene's run.sweep.
    follow: each point starts from the previous point's final state; reverse: walk the grid
    backwards (None: the scene's setting). periods, transient_periods and the record keywords
    as for simulate().

    The Result is laid out as a sweep file (docs/results.md, "Sweeps"): ``result.sweep.values``
    (P × k), ``result.sweep.status``, fixed-size groups stacked on a leading point axis
    (``result.stats.sticking_fraction``: P × periods × stops), events and contacts concatenated
    with a ``point`` column; ``result.point_rows(group, p)`` gives point p's rows. The data are
    those of ``vibro run`` on the same scene, whatever the number of threads. Every point is
    validated before any runs (SceneError names the point); Interrupted carries the finished ones.
    """
    scene = _scene_of(scene)
    doc = _prepared(scene, periods, transient_periods, record)
    if parameters is None:
        if scene.run_kind != "sweep":
            raise ValueError("sweep: give parameters={path: values}; the scene has no run.sweep")
    else:
        if not isinstance(parameters, dict) or not 1 <= len(parameters) <= 2:
            raise ValueError("sweep: parameters must be a dict {path: values} of one or two paths")
        doc.replace("run.sweep.parameters", json.dumps(_axes("parameters", parameters)))
    for key, flag in (("follow", follow), ("reverse", reverse)):
        if flag is not None:
            doc.replace("run.sweep." + key, json.dumps(bool(flag)))
    _only_kind(doc, "sweep")
    return _run(doc, threads, output, force, progress)


def locate(scene, path=None, values=None, *, transient_periods=None, output=None, force=False, threads=None,
           progress=None, **options):
    """Finds and locates the bifurcations of the scene's periodic orbits along one path (run.kind: locate).

    path, values: the scanned scene path and its grid (None: the scene's run.locate). options:
    the other keys of run.locate (tolerance, periodicity, max_period, max_periods, jump). The
    Result holds /scan, /phases and /transitions (``result.transitions.parameter``, ``.kind``
    whose names are ``result.transitions.labels("kind")["names"]``). threads: for the bisections.
    """
    if path is not None:
        if values is None and not any(key in options for key in _GRID_KEYS):
            raise ValueError("locate: give the grid values with the path")
        options.update(path=path, **({} if values is None else {"values": values}))
    elif not options and (scene := _scene_of(scene)).run_kind != "locate":
        raise ValueError("locate: give path and values; the scene has no run.locate")
    return _run_kind("locate", scene, options, transient_periods, output, force, threads, progress)


def continuation(scene, path=None, range=None, *, transient_periods=None, output=None, force=False, threads=None,
                 progress=None, **options):
    """Follows the scene's branch of periodic orbits in one parameter (run.kind: continue):
    pseudo-arclength continuation with Newton shooting and exact Jacobians, with the Floquet
    multipliers of every orbit and its bifurcations located (folds, period doublings with branch
    switching, Neimark–Sacker points, grazings, risings; contact phases and chatter appearing or
    vanishing bracketed).

    path, range: the parameter and its limits [min, max] (None: the scene's run.continue); the
    branch starts at the scene's value of path. options: the other keys of run.continue
    (direction "up"/"down", period, phase, step, min_step, max_step, max_points, tolerance,
    locate, locate_tolerance, max_doublings, curve: a dict with path, range and optionally kinds,
    e.g. ["fold", "period_doubling"]). The Result holds
    /branch (``result.branch.p``, ``.stable``, ``.multipliers_real``, …), /branches,
    /bifurcations (``result.bifurcations.p``, ``.kind`` whose names are
    ``result.bifurcations.labels("kind")["names"]``) and, with a curve, /curve (and /codim2 with
    curves of folds, doublings or tori: their codimension-two points). One thread.
    """
    if path is not None:
        if range is None:
            raise ValueError("continuation: give the range [min, max] with the path")
        options.update(path=path, range=[float(v) for v in range])
    elif not options and (scene := _scene_of(scene)).run_kind != "continue":
        raise ValueError("continuation: give path and range; the scene has no run.continue")
    return _run_kind("continue", scene, options, transient_periods, output, force, threads, progress)


def _kind_function(name, summary, section):
    """The function of run kind `name` (one without a hand-written one above): its section's keys
    as keywords."""
    def run_kind(scene, *, transient_periods=None, output=None, force=False, threads=None, progress=None, **keys):
        return _run_kind(name, scene, keys, transient_periods, output, force, threads, progress)
    run_kind.__name__ = run_kind.__qualname__ = _FUNCTION_NAMES.get(name, name)
    keys = (f"the keys of run.{section} (docs/scenes.md) as keywords: a grid as ``path=``, "
            f"``values=`` (or ``linspace=``, ``logspace=``), ``parameters={{path: values, …}}`` for "
            f"two; the scene's own run.{section}, if any, keeps the keys not given."
            if section else "no section of its own.")
    run_kind.__doc__ = f"""{summary[0].upper()}{summary[1:]} (run.kind: {name}).

    Keywords: transient_periods (run.transient_periods) and {keys} The Result holds its groups
    (docs/results.md), e.g. ``result["{name}"]``.
""" + _COMMON
    return run_kind


def run(scene, *, output=None, force=False, threads=None, progress=None):
    """Runs the scene as ``vibro run`` does: its own run.kind, record and settings (output, force,
    threads, progress as for the run functions)."""
    return _run(_scene_of(scene)._doc.copy(), threads, output, force, progress)


def run_kinds():
    """The run kinds ``vibro run`` knows (run.kind, docs/scenes.md): a dict name -> one-line summary,
    in the order of the table the command dispatches on."""
    return {name: summary for name, summary, _, _ in _run_kinds()}


def run_function(kind):
    """The function that runs `kind` (a run.kind value), e.g. run_function("continue") is continuation."""
    if kind not in _KIND_FUNCTIONS:
        raise ValueError(f"{kind!r}: not a run kind (run kinds: {', '.join(_KIND_FUNCTIONS)})")
    return _KIND_FUNCTIONS[kind]


def _run_kind(name, scene, keys, transient_periods, output, force, threads, progress=None):
    """Runs `scene` as run.kind `name` with `keys` replacing keys of its run section."""
    scene = _scene_of(scene)
    section, missing = _KIND_SECTIONS[name]
    doc = _prepared(scene, None, transient_periods, {})
    if keys and section is None:
        raise TypeError(f"{_FUNCTION_NAMES.get(name, name)}: unknown keyword {sorted(keys)[0]!r} "
                        f"(run.kind: {name} has no section of its own)")
    if missing and scene.run_kind != name and not keys:
        raise ValueError(f"{_FUNCTION_NAMES.get(name, name)}: the scene has no run.{section} (it is a "
                         f"run.kind: {scene.run_kind} scene): give its keys as keywords "
                         f"({missing.removeprefix('missing: ')})")
    if any(key in keys for key in _GRID_KEYS):
        for key in _GRID_KEYS:
            doc.replace(f"run.{section}.{key}", "")
    for key, value in keys.items():
        where = f"run.{section}.{key}"
        if key in _GRID_KEYS and key != "values" or key == "range":
            value = _plain(value, where)
        elif key == "values":
            value = _values(where, value)
        elif key == "parameters" and isinstance(value, dict):
            value = _axes(where, value)
        else:
            value = _plain(value, where)
        doc.replace(where, json.dumps(value))
    _only_kind(doc, name)
    try:
        return _run(doc, threads, output, force, progress)
    except SceneError as e:
        # A value given as a keyword has no place in the scene's text: name the keyword instead.
        path = getattr(e, "path", "")
        for key in keys:
            where = f"run.{section}.{key}"
            if path == where or path.startswith((where + ".", where + "[")):
                raise _keyword_error(e, f"{_FUNCTION_NAMES.get(name, name)}({key}=…)") from None
        if section and scene.run_kind != name and path.startswith(f"run.{section}"):
            raise _keyword_error(e, f"{_FUNCTION_NAMES.get(name, name)}(…)") from None  # a section of keywords only
        raise


def _keyword_error(e, keyword):
    """SceneError `e` about a value given as `keyword`: 'keyword: key.path: problem'."""
    error = SceneError(f"{keyword}: {e.path}: {e.problem}")
    error.file, error.line, error.column, error.path, error.problem = keyword, 0, 0, e.path, e.problem
    return error


def _axes(where, parameters):
    """{path: values} as a run section's list of axes [{path, values}]."""
    return [{"path": str(path), "values": _values(str(path), values)}
            for path, values in parameters.items()]


def _only_kind(doc, kind):
    """Makes `doc` a run of `kind`: run.kind set and every other kind's own section of run removed
    (the scene may come from a file of another kind: a diagram's run.diagram would be refused)."""
    doc.replace("run.kind", kind)
    for name, _, section, _ in _run_kinds():
        if section is not None and name != kind:
            doc.replace("run." + section, "")


def read(path):
    """The Result of a result file written by ``vibro run`` or ``Result.save``: the same object
    as the run gave (its data read into memory; the file may then change or go)."""
    return Result(_Image.load(str(path)))


def _scene_of(scene):
    """A Scene from a Scene, a path (str or os.PathLike) or YAML text (a str with a line break)."""
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, os.PathLike):
        return Scene.load(os.fspath(scene))
    if isinstance(scene, str):
        return Scene.from_text(scene) if "\n" in scene else Scene.load(scene)
    raise TypeError(f"expected a vibro.Scene, a scene file's path or YAML text, got {type(scene).__name__}")


def _prepared(scene, periods, transient_periods, record):
    doc = scene._doc.copy()
    for key, value in (("periods", periods), ("transient_periods", transient_periods)):
        if value is not None:
            doc.replace("run." + key, _number(key, value))
    if record:
        doc.replace("record", json.dumps(_record(scene.record, record)))
    return doc


def _record(current, given):
    """The record: section for the keywords `given`: record= (or the scene's `current` choice),
    then each single keyword replacing the choice for its observer (docs/scenes.md, record)."""
    allowed = set(_OBSERVERS) | {"samples", "sample_times", "record", "section"}
    unknown = sorted(set(given) - allowed)
    if unknown:
        raise TypeError(f"unknown keyword {unknown[0]!r} (record keywords: {', '.join(sorted(allowed))})")
    if "record" in given:
        out = _plain(given["record"], "record")
        if not isinstance(out, dict):
            raise TypeError(f"record: expected a dict (a record: section), found {given['record']!r}")
    else:
        # impact_map only when on: a scene without it keeps the record section it always had.
        out = {k: bool(current[k]) for k in _OBSERVERS if k != "impact_map" or current[k]}
        if current["samples_per_period"]:
            out["samples"] = {"per_period": current["samples_per_period"]}
        elif current["sample_times"]:
            out["samples"] = {"times": current["sample_times"]}
        if current.get("section"):
            out["section"] = dict(current["section"])
    if "section" in given:  # {coordinate: i | normal: [...], value: c, direction: ...}, or None: none
        if given["section"] is None:
            out.pop("section", None)
        else:
            out["section"] = _plain(given["section"], "section")
    for key in _OBSERVERS:
        if key in given:
            if not isinstance(given[key], (bool, np.bool_)):
                raise TypeError(f"{key}: expected True or False, found {given[key]!r}")
            out[key] = bool(given[key])
    if "samples" in given and "sample_times" in given:
        raise TypeError("give samples (per period) or sample_times, not both")
    if "samples" in given:
        count = given["samples"]
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
            raise TypeError(f"samples: expected a number of samples per period ≥ 0, found {count!r}")
        out["samples"] = {"per_period": int(count)}
    if "sample_times" in given:
        out["samples"] = {"times": _values("sample_times", given["sample_times"])}
    if out.get("samples") in ({"per_period": 0}, {"times": []}):
        del out["samples"]
    return {k: v for k, v in out.items() if v is not False}


def _run(doc, threads, output=None, force=False, progress=None):
    count = 0 if threads is None else int(threads)
    if count < 0:
        raise ValueError(f"threads: expected a number ≥ 0 (0: all cores), found {threads!r}")
    if output is not None and not force and os.path.exists(output):
        raise ResultError(f"{os.fspath(output)}: exists; give force=True to replace it")
    show, callback = 0, None
    if progress is True:
        show = 1 if sys.stderr.isatty() else 2
    elif callable(progress):
        callback = progress
    elif progress not in (None, False):
        raise TypeError(f"progress: expected True, False, None or a callable(done, total), found {progress!r}")
    image, exit_code, summary, interrupted = doc.run(count, show, callback)
    # No image: interrupted in a set-up before the run held anything (result None).
    result = Result(_Image.from_bytes(image), exit_code, summary) if len(image) else None
    if interrupted:
        if result is None:
            raise Interrupted("vibro: run interrupted during its set-up; nothing was computed (.result is None)", None)
        raise Interrupted("vibro: run interrupted; the partial result is in .result", result)
    if output is not None:
        result.save(os.fspath(output), overwrite=bool(force))
    return result


# --- One orbit at a time ---------------------------------------------------------------------------

def _state(name, value):
    return None if value is None else _array(name, value).ravel()


def _multipliers(d):
    return types.SimpleNamespace(values=np.array(d["values"], dtype=complex), stable=d["stable"],
                                 spectral_radius=d["spectral_radius"], rate=d["rate"],
                                 structural_zeros=d["structural_zeros"])


def tangent_map(scene, x=None, v=None, *, t0=None, periods=1.0):
    """The exact linearisation of the flow over ``periods`` forcing periods from the state (t0, x, v)
    (None: the scene's initial state), on the dense engine (framework/analysis, linearisation.hpp):
    flows between events and the saltation matrices of the impacts, sticks and releases.

    Returns a namespace with x1, v1 (the end state), jacobian (2n × 2n, ∂(x1, v1)/∂(x0, v0)),
    free_dimension (least tangent dimension along the run: 2n when no stop is held), events,
    status and message (of the run; the map is valid only when status is 'completed'), and, when
    ``periods`` is a whole number k, multipliers (as multipliers() gives them for that map).
    """
    scene = _scene_of(scene)
    span = _number("periods", periods)
    t_start = scene.t0 if t0 is None else float(_number("t0", t0))
    k = int(float(span)) if float(span) == int(float(span)) and float(span) >= 1 else 0
    d = scene._doc.tangent_map(t_start, t_start + float(span) * scene.period, _state("x", x), _state("v", v), k)
    out = types.SimpleNamespace(**{key: (np.array(value) if key in ("x0", "v0", "x1", "v1", "jacobian") else value)
                                   for key, value in d.items() if key != "multipliers"})
    if "multipliers" in d:
        out.multipliers = _multipliers(d["multipliers"])
    return out


def multipliers(scene, x=None, v=None, *, t0=None, period=1):
    """The Floquet multipliers of the k-period map (k = period) at the state (t0, x, v): the
    eigenvalues of its exact Jacobian (the reduced map where stops are held; their structural
    zeros are exact 0s). Meaningful at a point of a period-k orbit (see shoot()); elsewhere the
    eigenvalues of that map. Returns a namespace: values (complex array, by decreasing modulus),
    stable, spectral_radius, rate (per period), structural_zeros."""
    if isinstance(period, bool) or not isinstance(period, (int, np.integer)) or period < 1:
        raise ValueError(f"period: expected a whole number of forcing periods ≥ 1, found {period!r}")
    m = tangent_map(scene, x, v, t0=t0, periods=int(period))
    if m.status != "completed":
        raise ValueError(f"multipliers: the run over {period} periods stopped early ({m.status}): {m.message}")
    return m.multipliers


def shoot(scene, x=None, v=None, *, t=None, period=1, phase=0.0, tolerance=1e-11, max_iterations=40):
    """A periodic orbit by Newton shooting on the stroboscopic map with exact Jacobians, on the
    dense engine (shooting.hpp; the run kind ``orbit`` does the same after a transient): from the
    guess (t, x, v) (None: the scene's initial state), for an orbit of ``period`` forcing periods
    with its section at forcing phase ``phase`` (radians).

    Returns a namespace: status ('converged', 'not converged', 'map failed', 'singular Jacobian'),
    message, x, v (the state on the orbit at t0, the section time used), t0, phase, residual,
    residuals, iterations, period, minimal_period, jacobian (of the last map) and, when
    converged, multipliers (as multipliers() gives them). Never a false orbit: check status.
    """
    scene = _scene_of(scene)
    if isinstance(period, bool) or not isinstance(period, (int, np.integer)) or period < 1:
        raise ValueError(f"period: expected a whole number of forcing periods ≥ 1, found {period!r}")
    guess_t = None if t is None else float(_number("t", t))
    d = scene._doc.shoot(int(period), float(_number("phase", phase)), float(_number("tolerance", tolerance)),
                         int(max_iterations), guess_t, _state("x", x), _state("v", v))
    out = types.SimpleNamespace(**{key: (np.array(value) if key in ("x", "v", "jacobian", "residuals") else value)
                                   for key, value in d.items() if key != "multipliers"})
    if "multipliers" in d:
        out.multipliers = _multipliers(d["multipliers"])
    return out


# --- Results -------------------------------------------------------------------------------------

class Result:
    """A run's results: the groups and datasets of its HDF5 file (docs/results.md) as numpy arrays.

    ``result.events`` (a Group; also ``result["events"]``) and ``result.events.t`` (an array;
    also ``result["events/t"]``) name exactly what the file names. Only what was recorded
    exists (``result.groups`` lists it). ``result.meta`` is /meta's attributes (provenance,
    tolerances, counts, ``status``, ``message``); ``result.scene`` the /scene group (the scene's
    text, attribute ``yaml``, and its resolved values). Arrays are read-only and read on first use.

    ``result.save(path)`` writes the file (``vibro run``'s, bit for bit in its data);
    ``vibro.read(path)`` gives this object back. ``summary`` and ``exit_code`` are what
    ``vibro run`` prints and returns (None for a Result read from a file).
    """

    def __init__(self, image, exit_code=None, summary=None):
        self._image = image
        self._arrays = {}
        self.exit_code = exit_code
        self.summary = summary
        objects = image.objects()
        self._datasets = {o for o in objects if image.is_dataset(o)}
        self._groups = {o for o in objects if o not in self._datasets}

    @property
    def groups(self):
        """The top-level groups present ('scene', 'meta', 'events', 'sweep', …)."""
        return sorted(g[1:] for g in self._groups if g.count("/") == 1)

    @property
    def meta(self):
        """/meta's attributes: version, git_commit, date, threads, tolerances, counts, status."""
        return self._image.attributes("/meta")

    status = property(lambda self: self.meta["status"], doc="/meta status ('completed', …).")
    frame = property(lambda self: self.meta.get("frame"),
                     doc="A base-excited scene's frame of the states written (/meta frame, record.frame): "
                         "'absolute' or 'relative'; None without a base.")
    message = property(lambda self: self.meta["message"], doc="/meta message: why it stopped early.")

    def __getitem__(self, path):
        path = "/" + path.strip("/")
        if path in self._datasets:
            return self._array(path)
        if path in self._groups:
            return Group(self, path)
        raise KeyError(f"{path}: not in this result (it has: {', '.join(self.groups)})")

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        if "/" + name in self._groups:
            return Group(self, "/" + name)
        raise AttributeError(f"{name}: no such group in this result (it has: {', '.join(self.groups)})")

    def __contains__(self, path):
        path = "/" + path.strip("/")
        return path in self._groups or path in self._datasets

    def __dir__(self):
        return sorted(set(super().__dir__()) | set(self.groups))

    def datasets(self):
        """Every dataset's path, sorted ('/events/t', …)."""
        return sorted(self._datasets)

    def attributes(self, path):
        """The attributes of a group or dataset (dict of str, list of str, int or float)."""
        return self._image.attributes("/" + path.strip("/"))

    def point_rows(self, group, p):
        """Sweeps: the rows of point p of a concatenated group (events, contacts) as a dict of
        arrays, or of a stacked group (samples, poincare, stats) without its padding."""
        g = self[group]
        rows = g.rows
        if g.attrs.get("stacking") == "concatenated":
            start = int(np.sum(rows[:p]))
            return {k: g[k][start:start + rows[p]] for k in g.keys() if k not in ("rows", "point")}
        return {k: g[k][p, :rows[p]] for k in g.keys() if k != "rows"}

    def save(self, path, overwrite=False):
        """Writes the result file (whole or not at all). Refuses to replace an existing file
        unless overwrite=True (ResultError)."""
        self._image.save(str(path), bool(overwrite))

    def to_bytes(self):
        """The bytes of the result file."""
        return self._image.bytes()

    def _array(self, path):
        if path not in self._arrays:
            a = self._image.dataset(path)
            a.flags.writeable = False
            self._arrays[path] = a
        return self._arrays[path]

    def __repr__(self):
        return f"<vibro.Result {self.meta.get('status')}: groups {', '.join(self.groups)}>"


class Group:
    """One group of a Result: its datasets as read-only numpy arrays, by key or attribute.

    ``group.keys()`` lists them; ``group.attrs`` holds the group's attributes (e.g. ``stacking``);
    ``group.labels(name)`` a dataset's attributes (``names`` of an enumeration such as
    /events/kind, ``stops`` of /stats columns).
    """

    def __init__(self, result, path):
        self._result = result
        self.path = path

    def keys(self):
        """The dataset names of this group, sorted."""
        prefix = self.path + "/"
        return sorted(d[len(prefix):] for d in self._result._datasets
                      if d.startswith(prefix) and "/" not in d[len(prefix):])

    @property
    def attrs(self):
        """The group's attributes."""
        return self._result.attributes(self.path)

    def labels(self, name):
        """The attributes of dataset `name` (its labels: ``names``, ``stops``, ``columns``)."""
        return self._result.attributes(self.path + "/" + name)

    def __getitem__(self, name):
        return self._result[self.path + "/" + name]

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        if name in self.keys():
            return self[name]
        raise AttributeError(f"{self.path}: no dataset {name!r} (it has: {', '.join(self.keys())})")

    def __contains__(self, name):
        return name in self.keys()

    def __dir__(self):
        return sorted(set(super().__dir__()) | set(self.keys()))

    def __repr__(self):
        shapes = ", ".join(f"{k}{self[k].shape}" for k in self.keys())
        return f"<vibro.Group {self.path}: {shapes}>"


# --- The function of every run kind ------------------------------------------------------------
# From the table `vibro run` dispatches on: a kind without a hand-written function above gets one.
_KIND_SECTIONS = {name: (section, missing) for name, _, section, missing in _run_kinds()}
_KIND_FUNCTIONS = {}
for _name, _summary, _section, _ in _run_kinds():
    _function = _FUNCTION_NAMES.get(_name, _name)
    if _function not in globals():
        globals()[_function] = _kind_function(_name, _summary, _section)
    else:
        globals()[_function].__doc__ += _COMMON
    _KIND_FUNCTIONS[_name] = globals()[_function]
    __all__.append(_function)
del _name, _summary, _section, _function

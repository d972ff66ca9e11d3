"""One function per run kind, generated from the table `vibro run` dispatches on: each runs its
kind on a scene written for any kind (a Scene, a file path or YAML text) with its run section's
keys as keywords, gives what `vibro run` gives on the equivalent scene file, writes the result
file when asked, and raises the command's errors (keyword values named by their keyword). And
one orbit at a time: shooting, the tangent map and the multipliers of a state."""
import numpy as np
import pytest
import vibro
from conftest import PAPER, differences, same_bits, write

# Each kind: its run section as a scene file writes it, and the same as keywords of its function
# (small grids and budgets: each run takes well under a second).
KINDS = {
    "simulate": ("run: {kind: simulate, transient_periods: 1, periods: 1}\n",
                 dict(transient_periods=1, periods=1)),
    "sweep": ("run: {kind: sweep, transient_periods: 1, periods: 1, sweep: {parameters: "
              "[{path: forcing.frequency, values: [0.25, 0.26]}]}}\n",
              dict(parameters={"forcing.frequency": [0.25, 0.26]}, transient_periods=1, periods=1)),
    "locate": ("run: {kind: locate, transient_periods: 5, locate: {path: forcing.frequency, "
               "linspace: [0.25, 0.26, 2], max_periods: 100}}\n",
               dict(path="forcing.frequency", linspace=[0.25, 0.26, 2], max_periods=100, transient_periods=5)),
    "continue": ("run: {kind: continue, transient_periods: 50, continue: {path: forcing.frequency, "
                 "range: [0.254, 0.256], max_points: 4}}\n",
                 dict(path="forcing.frequency", range=[0.254, 0.256], max_points=4, transient_periods=50)),
    "basin": ("run: {kind: basin, transient_periods: 1, basin: {parameters: [{path: 'initial.x[0]', linspace: [0.0, 0.001, 2]}, "
              "{path: 'initial.v[0]', linspace: [0.0, 0.001, 2]}], max_period: 2, max_periods: 20}}\n",
              dict(parameters={"initial.x[0]": np.linspace(0.0, 0.001, 2), "initial.v[0]": [0.0, 0.001]},
                   max_period=2, max_periods=20, transient_periods=1)),
    "diagram": ("run: {kind: diagram, transient_periods: 2, diagram: {path: forcing.frequency, "
                "values: [0.25, 0.26], transient: 1, points: 4, max_period: 2}}\n",
                dict(path="forcing.frequency", values=np.array([0.25, 0.26]), transient=1, points=4, max_period=2,
                     transient_periods=2)),
    "lyapunov": ("run: {kind: lyapunov, transient_periods: 2, lyapunov: {transient: 1, align: 1, periods: 2}}\n",
                 dict(transient=1, align=1, periods=2, transient_periods=2)),
    "orbit": ("run: {kind: orbit, transient_periods: 5, orbit: {period: 1}}\n",
              dict(transient_periods=5, period=1)),
}
# What names the scene rather than the results: its text and where it was read from.
SCENE_TEXT = {("/scene", "yaml"), ("/scene", "file")}


def function(kind):
    return getattr(vibro, {"continue": "continuation"}.get(kind, kind))


def test_every_run_kind_has_its_function():
    assert set(KINDS) == set(vibro.run_kinds()), "a run kind without a case here"
    for kind in vibro.run_kinds():
        f = function(kind)
        assert vibro.run_function(kind) is f and f.__name__ in vibro.__all__
        assert f.__doc__ and "Returns a Result" in f.__doc__
    assert set(vibro.__all__) <= set(dir(vibro))
    with pytest.raises(ValueError, match="not a run kind"):
        vibro.run_function("diagrams")


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_each_function_gives_what_vibro_run_gives(kind, tmp_path):
    """The function on a scene of another kind equals `vibro run` on the kind's own scene file."""
    text, keywords = KINDS[kind]
    other = "orbit" if kind != "orbit" else "diagram"
    reference = write(tmp_path, "own.yaml", PAPER + text)
    vibro.run(str(reference), output=tmp_path / "own.h5")
    scene = vibro.Scene.from_text(PAPER + KINDS[other][0])
    result = function(kind)(scene, output=tmp_path / "function.h5", threads=1, **keywords)
    assert result.scene.attrs["run_kind"] == kind
    assert scene.run_kind == other, "the scene was changed"
    assert differences(tmp_path / "function.h5", tmp_path / "own.h5", SCENE_TEXT) == []


@pytest.mark.parametrize("other", ["diagram", "basin", "lyapunov", "orbit", "locate"])
def test_simulate_and_continuation_on_a_file_of_another_kind(other, tmp_path):
    path = write(tmp_path, "other.yaml", PAPER + KINDS[other][0])
    r = vibro.simulate(path, periods=1, transient_periods=0, record={})
    assert r.status == "completed" and r.scene.attrs["run_kind"] == "simulate"
    c = vibro.continuation(str(path), "forcing.frequency", [0.254, 0.256], max_points=3, transient_periods=50)
    assert c.scene.attrs["run_kind"] == "continue" and len(c.branch.p) >= 2
    assert c.branch.p.min() < 0.255 < c.branch.p.max()  # through the scene's value


def test_a_scene_as_text_and_keywords_over_its_own_section(tmp_path):
    text = PAPER + KINDS["diagram"][0]
    r = vibro.diagram(text, points=6, max_period=3)  # the file's path and grid, kept
    assert r.diagram.x_up.shape == (2, 6, 2)
    assert list(r.diagram.parameter) == [0.25, 0.26]
    r = vibro.diagram(text, linspace=[0.25, 0.27, 3])  # replaces the file's values
    assert list(r.diagram.parameter) == list(np.linspace(0.25, 0.27, 3))


def test_output_is_written_and_not_replaced_unasked(tmp_path):
    out = tmp_path / "o.h5"
    r = vibro.orbit(PAPER + KINDS["orbit"][0], output=out)
    assert same_bits(vibro.read(out)["orbit/x"], r.orbit.x)
    with pytest.raises(vibro.ResultError, match="exists; give force=True"):
        vibro.orbit(PAPER + KINDS["orbit"][0], output=out)
    vibro.orbit(PAPER + KINDS["orbit"][0], output=out, force=True, period=2)
    assert int(vibro.read(out).attributes("orbit")["period"]) == 2


# One bad keyword per function: the problem is the loader's, the place the keyword.
ERRORS = {
    "simulate": (dict(periods=0), vibro.SceneError, "run.periods"),
    "sweep": (dict(parameters={"forcing.frequenc": [0.25]}), vibro.SceneError, "does not name a number"),
    "locate": (dict(path="forcing.frequency", values=[0.25, 0.26], max_period=0), vibro.SceneError,
               r"^locate\(max_period=…\): run.locate.max_period: expected"),
    "continue": (dict(path="forcing.frequency", range=[0.26, 0.27]), vibro.SceneError,
                 r"^continuation\(range=…\): run.continue.range: the scene's value 0.255 lies outside"),
    "basin": (dict(parameters={"initial.x[0]": [0.0, 0.001], "initial.v[0]": [0.0, 0.001]}, max_period=2,
                   max_periods=2), vibro.SceneError, r"^basin\(max_periods=…\): run.basin.max_periods: expected at least"),
    "diagram": (dict(path="forcing.frequency", values=[0.25, 0.26], points=0), vibro.SceneError,
                r"^diagram\(points=…\): run.diagram.points: expected a whole number in \[1, 100000\], found 0"),
    "lyapunov": (dict(count=9), vibro.SceneError, r"^lyapunov\(count=…\): run.lyapunov.count"),
    "orbit": (dict(periodd=1), vibro.SceneError, r"^orbit\(periodd=…\): .*unknown key 'periodd'; did you mean 'period'"),
}


@pytest.mark.parametrize("kind", sorted(ERRORS))
def test_each_function_raises_the_commands_errors(kind):
    keywords, error, message = ERRORS[kind]
    with pytest.raises(error, match=message):
        function(kind)(PAPER + KINDS["orbit" if kind != "orbit" else "diagram"][0], **keywords)


def test_errors_in_the_file_keep_its_place(tmp_path):
    """An error of the scene file itself is the command's message, file:line:column first."""
    path = write(tmp_path, "bad.yaml", PAPER.replace("restitution: 0.7", "restitution: 1.7", 1) + KINDS["orbit"][0])
    for kind in KINDS:
        with pytest.raises(vibro.SceneError) as raised:
            function(kind)(path, **KINDS[kind][1])
        assert str(raised.value).startswith(f"{path}:") and raised.value.line > 0, kind
    with pytest.raises(ValueError, match="the scene has no run.diagram .*give its keys as keywords"):
        vibro.diagram(path.read_text().replace("1.7", "0.7"))
    with pytest.raises(TypeError, match="expected a vibro.Scene, a scene file's path or YAML text"):
        vibro.orbit(42)
    with pytest.raises(vibro.SceneError, match="nothing.yaml"):
        vibro.orbit(tmp_path / "nothing.yaml")


def test_shooting_and_multipliers_match_the_orbit_run():
    scene = vibro.Scene.from_text(PAPER + KINDS["orbit"][0])
    run = vibro.orbit(scene)
    t0 = float(run.attributes("orbit")["t0"])
    o = vibro.shoot(scene, run.orbit.x, run.orbit.v, t=t0)
    assert o.status == "converged" and o.residual <= 1e-11
    # Started on the orbit the run found (to 1e-11): the same orbit, to the tolerance's scale.
    assert np.max(np.abs(o.x - run.orbit.x)) <= 1e-9
    ours = np.sort_complex(o.multipliers.values)
    theirs = np.sort_complex(run.orbit.multipliers_real + 1j * run.orbit.multipliers_imag)
    assert np.max(np.abs(ours - theirs)) <= 1e-8
    m = vibro.multipliers(scene, o.x, o.v, t0=o.t0)
    assert np.max(np.abs(np.sort_complex(m.values) - ours)) <= 1e-8 and m.stable == o.multipliers.stable
    # A guess that is no orbit: a failure, never a false orbit.
    far = vibro.shoot(scene, [0.05, 0.05], [0.0, 0.0], max_iterations=1)
    assert far.status == "not converged" and far.residual > 1e-11 and not hasattr(far, "multipliers")
    with pytest.raises(ValueError, match=r"initial state violates stops\[1\] \(s2\)"):
        vibro.shoot(scene, [5.0, 5.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="period: expected a whole number"):
        vibro.shoot(scene, period=0)
    with pytest.raises(ValueError, match="x"):
        vibro.multipliers(scene, [0.0, 0.0, 0.0])


def test_tangent_map_of_a_free_oscillator_is_its_matrix_exponential():
    """No stop: the map over a span τ is exp(Aτ), A = [[0, I], [−K, −C]] (M = I)."""
    K, C = np.array([[2.0, -1.0], [-1.0, 2.0]]), np.array([[0.1, 0.0], [0.0, 0.2]])
    scene = vibro.Scene.from_matrices(np.eye(2), C, K, frequency=1.3, cosine=[0.4, 0.0], x0=[0.1, -0.2])
    m = vibro.tangent_map(scene, periods=0.7)
    assert m.status == "completed" and m.jacobian.shape == (4, 4) and not hasattr(m, "multipliers")
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-K, -C]])
    w, V = np.linalg.eig(A * 0.7 * scene.period)
    expected = (V @ np.diag(np.exp(w)) @ np.linalg.inv(V)).real
    assert np.max(np.abs(m.jacobian - expected)) <= 1e-12 * np.max(np.abs(expected)) * 100
    whole = vibro.tangent_map(scene, periods=2)
    assert np.allclose(np.sort_complex(whole.multipliers.values),
                       np.sort_complex(np.linalg.eigvals(whole.jacobian)), rtol=0, atol=1e-12)


# The Duffing impact oscillator (experiments/examples/duffing_impact.yaml): a cubic spring, so the
# Taylor engine runs every kind.
DUFFING = """\
model: {chain: {masses: [1], left_wall: {spring: 1, damper: 0.05}}}
forcing: {frequency: 0.255, cosine: [0.8]}
stops: [{mass: 0, side: upper, position: 0.6, restitution: 0.8, name: stop}]
parameters: {beta: 0.5}
forces: [{cubic_spring: {mass: 0, coefficient: beta}}]
initial: {x: [0], v: [0]}
"""


@pytest.mark.parametrize("kind", ["sweep", "locate", "basin", "diagram"])
def test_functions_on_a_scene_with_forces_give_what_vibro_run_gives(kind, tmp_path):
    text, keywords = KINDS[kind]
    reference = write(tmp_path, "own.yaml", DUFFING + text)
    vibro.run(str(reference), output=tmp_path / "own.h5")
    result = function(kind)(vibro.Scene.from_text(DUFFING + KINDS["orbit"][0]), output=tmp_path / "function.h5",
                            threads=1, **keywords)
    assert result.scene.attrs["run_kind"] == kind
    assert result.meta["engine"] == "taylor"
    assert differences(tmp_path / "function.h5", tmp_path / "own.h5", SCENE_TEXT) == []

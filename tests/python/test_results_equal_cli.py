"""Results through Python equal `vibro run`'s file for the same scene, dataset by dataset, bit for
bit, for each run kind; result.save() writes that file (its attributes too, but for the date,
wall time and thread count of the run) and vibro.read() gives the same result back."""
import vibro
from conftest import PAPER, differences, result_differences, write

SIMULATE = PAPER + "run: {kind: simulate, transient_periods: 20, periods: 3}\n"
SWEEP = PAPER + """\
run:
  kind: sweep
  transient_periods: 10
  periods: 2
  sweep:
    parameters:
      - {path: forcing.frequency, values: [0.25, 0.255, 0.2561, 0.26, 0.27]}
"""
FOLLOWED_2D = PAPER + """\
run:
  kind: sweep
  transient_periods: 5
  periods: 1
  sweep:
    follow: true
    parameters:
      - {path: "forcing.cosine[0]", values: [0.45, 0.5]}
      - {path: forcing.frequency, values: [0.255, 0.26, 0.265]}
"""
LOCATE = PAPER + """\
run:
  kind: locate
  transient_periods: 100
  locate: {path: forcing.frequency, linspace: [0.2555, 0.2565, 3], tolerance: 1e-5}
"""

CONTINUE = PAPER + """\
run:
  kind: continue
  transient_periods: 100
  continue: {path: forcing.frequency, range: [0.2559, 0.2561], step: 0.05, max_step: 0.2}
"""


def check_same(tmp_path, cli, text, threads_cli, **python):
    scene_file = write(tmp_path, "scene.yaml", text)
    code, err = cli("run", scene_file, "-o", "cli.h5", "--threads", threads_cli)
    assert code == 0, err
    cli_file = tmp_path / "cli.h5"
    result = vibro.run(vibro.Scene.load(scene_file), **python)
    assert result.exit_code == 0 and result.status == "completed", result.summary
    assert result_differences(result, cli_file) == []
    result.save(tmp_path / "python.h5")
    assert differences(tmp_path / "python.h5", cli_file) == []
    back = vibro.read(tmp_path / "python.h5")
    assert result_differences(back, cli_file) == []
    assert back.meta == result.meta and back.groups == result.groups
    return result


def test_simulate_equals_the_command(tmp_path, cli):
    result = check_same(tmp_path, cli, SIMULATE, 1)
    assert {"events", "contacts", "samples", "poincare", "stats"} <= set(result.groups)
    assert result.meta["sticks"] > 0 and result.meta["chatters"] > 0  # the data are not trivial


def test_sweep_equals_the_command_whatever_the_threads(tmp_path, cli):
    for threads in (1, 2):
        result = check_same(tmp_path, cli, SWEEP, 2, threads=threads)
        assert result.sweep.values.shape == (5, 1)
        assert result.stats.sticking_fraction.shape == (5, 2, 2)
        (tmp_path / "cli.h5").unlink()
        (tmp_path / "python.h5").unlink()


def test_followed_2d_sweep_equals_the_command(tmp_path, cli):
    result = check_same(tmp_path, cli, FOLLOWED_2D, 2, threads=2)
    assert list(result.sweep.values[:, 1]) == [0.255, 0.26, 0.265] * 2


def test_locate_equals_the_command(tmp_path, cli):
    result = check_same(tmp_path, cli, LOCATE, 2, threads=2)
    assert {"scan", "phases", "transitions"} <= set(result.groups)
    names = result.transitions.labels("kind")["names"]
    assert "rising" in [names[k] for k in result.transitions.kind]  # rising lies in [0.2555, 0.2565]


def test_continuation_equals_the_command(tmp_path, cli):
    scene_text = CONTINUE.replace("frequency: 0.255", "frequency: 0.2559")
    result = check_same(tmp_path, cli, scene_text, 1)
    assert {"branch", "branches", "bifurcations"} <= set(result.groups)
    names = result.bifurcations.labels("kind")["names"]
    assert "rising" in [names[k] for k in result.bifurcations.kind]
    # continuation() with the path and range given equals the scene's own run.continue.
    scene = vibro.Scene.load(write(tmp_path, "c.yaml", scene_text))
    again = vibro.continuation(scene, "forcing.frequency", [0.2559, 0.2561], step=0.05, max_step=0.2)
    assert (again.branch.p == result.branch.p).all() and (again.bifurcations.p == result.bifurcations.p).all()


def test_keyword_runs_equal_the_scene_that_says_the_same(tmp_path, cli):
    """simulate() with periods and record keywords computes what a scene saying so gives `vibro run`."""
    said = write(tmp_path, "said.yaml", PAPER.split("record:")[0] + "record: {events: true, samples: {per_period: 20}}\n"
                 "run: {transient_periods: 20, periods: 3}\n")
    code, err = cli("run", said, "-o", "cli.h5")
    assert code == 0, err
    result = vibro.simulate(vibro.Scene.from_text(PAPER), periods=3, transient_periods=20,
                            record={"events": True, "samples": {"per_period": 20}})
    assert result_differences(result, tmp_path / "cli.h5") == []
    result.save(tmp_path / "python.h5")
    # The scene's text and file name are those of the scene each was given; all else is equal.
    assert differences(tmp_path / "python.h5", tmp_path / "cli.h5",
                       {("/scene", "yaml"), ("/scene", "file")}) == []


BASIN = PAPER.replace("frequency: 0.255", "frequency: 1.2") + """\
run:
  kind: basin
  basin:
    parameters:
      - {path: "initial.x[0]", linspace: [-0.29, 0.6, 6]}
      - {path: "initial.v[0]", linspace: [-0.6, 0.6, 5]}
    seed_stride: 3
"""
DIAGRAM = PAPER + """\
run:
  kind: diagram
  transient_periods: 50
  diagram: {path: forcing.frequency, values: [0.255, 0.26, 0.27], transient: 20, points: 4, max_period: 2}
"""
LYAPUNOV = PAPER + """\
run:
  kind: lyapunov
  lyapunov: {path: forcing.frequency, values: [0.255, 0.26], transient: 20, align: 5, periods: 20}
"""


def test_chaos_run_kinds_equal_the_command(tmp_path, cli):
    """run.kind: basin, diagram and lyapunov through vibro.run() (issue 16)."""
    for text, groups in ((BASIN, {"basin", "attractors"}), (DIAGRAM, {"diagram"}), (LYAPUNOV, {"lyapunov"})):
        result = check_same(tmp_path, cli, text, 2, threads=2)
        assert groups <= set(result.groups)
        for name in ("cli.h5", "python.h5"):
            (tmp_path / name).unlink()

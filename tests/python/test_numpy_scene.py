"""Scenes built from numpy: the paper's system built from M, C, K equals the YAML chain, bit for
bit in every dataset; bad arrays raise a clear ValueError (never a crash); the physics is checked
by the scene loader, with its messages."""
import numpy as np
import pytest
import vibro
from conftest import PAPER, differences, write

E = np.array([[2.0, -1.0], [-1.0, 1.0]])
STOPS = [{"mass": 0, "side": "lower", "position": -0.3, "restitution": 0.7, "name": "s1"},
         {"mass": 1, "side": "upper", "position": 0.1, "restitution": 0.7, "name": "s2"}]
RECORD = {"events": True, "contacts": True, "statistics": True, "poincare": True, "samples": {"per_period": 50}}


def paper(**changes):
    arguments = dict(M=np.eye(2), C=0.1 * E, K=E, frequency=0.255, cosine=[0.5, 0.0], stops=STOPS,
                     record=RECORD, run={"transient_periods": 20, "periods": 3}, name="wagg2004-fig2")
    arguments.update(changes)
    return vibro.Scene.from_matrices(**arguments)


def test_numpy_paper_system_equals_the_yaml_chain(tmp_path):
    from_yaml = vibro.Scene.from_text(PAPER + "run: {transient_periods: 20, periods: 3}\n")
    from_numpy = paper()
    assert from_numpy.engine == from_yaml.engine == "dense"
    vibro.run(from_yaml).save(tmp_path / "yaml.h5")
    result = vibro.run(from_numpy)
    result.save(tmp_path / "numpy.h5")
    assert result.meta["impacts"] > 50 and result.meta["sticks"] > 0
    assert np.array_equal(result.scene.stiffness, E) and np.array_equal(result.scene.damping, 0.1 * E)
    assert differences(tmp_path / "numpy.h5", tmp_path / "yaml.h5", {("/scene", "yaml"), ("/scene", "file")}) == []


def test_numpy_scene_paths_and_text():
    scene = paper()
    assert scene.file == "<numpy>" and scene.dof == 2 and scene.stops == ["s1", "s2"]
    assert scene.get("model.matrices.stiffness[0][1]") == -1.0
    scene.set("model.matrices.damping[1][1]", 0.2)
    with pytest.raises(vibro.SceneError, match=r"damping: entry \(0,1\) = .* the matrix must be symmetric"):
        scene.set("model.matrices.damping[0][1]", -0.2)
    again = vibro.Scene.from_text(scene.yaml)  # the generated text is a scene file
    assert again.get("forcing.frequency") == 0.255 and again.get("model.matrices.mass[1][1]") == 1.0


def test_numbers_round_trip_exactly():
    M = np.diag([1 / 3, np.pi])
    scene = paper(M=M, frequency=0.1 + 0.2)
    assert scene.get("model.matrices.mass[0][0]") == 1 / 3 and scene.frequency == 0.1 + 0.2


@pytest.mark.parametrize("changes, message", [
    (dict(M=np.eye(3)[:2]), r"M: expected a square n × n matrix, got an array of shape \(2, 3\)"),
    (dict(M=np.ones((2, 2, 2))), "M: expected a square"),
    (dict(M=[]), "M: expected a square"),
    (dict(C=np.eye(3)), r"C: expected shape \(2, 2\) like M"),
    (dict(K=np.array([[2.0, np.nan], [-1.0, 1.0]])), r"K\[0, 1\]: expected a finite number, found nan"),
    (dict(cosine=[0.5, np.inf]), r"cosine\[1\]: expected a finite number, found inf"),
    (dict(cosine=[0.5]), "cosine: expected 2 entries"),
    (dict(x0=[0, 0, 0]), "x0: expected 2 entries"),
    (dict(M=[["a", "b"], ["c", "d"]]), "M: expected an array of numbers"),
    (dict(frequency=float("nan")), "frequency: expected a finite number"),
    (dict(frequency="fast"), "frequency: expected a number"),
    (dict(stops=[{"mass": 0, "side": "lower", "position": np.nan, "restitution": 0.7}]),
     r"stops\[0\].position: expected a finite number"),
    (dict(stops=[{"mass": 0, "side": "lower", "position": object(), "restitution": 0.7}]),
     r"stops\[0\].position: expected a number, text"),
])
def test_bad_arrays_raise_value_error(changes, message):
    with pytest.raises(ValueError, match=message):
        paper(**changes)


@pytest.mark.parametrize("changes, message", [
    (dict(M=np.array([[1.0, 0.5], [0.0, 1.0]])), "model.matrices.mass: .*symmetric"),
    (dict(M=np.array([[1.0, 0.0], [0.0, -1.0]])), "model.matrices.mass: "),
    (dict(K=-E), "model.matrices.stiffness: "),
    (dict(stops=[{"mass": 0, "side": "lower", "postion": -0.3, "restitution": 0.7}]),
     r"stops\[0\].postion: unknown key 'postion'; did you mean 'position'\?"),
    (dict(stops=[{"mass": 5, "side": "lower", "position": -0.3, "restitution": 0.7}]),
     r"stops\[0\].mass: expected a whole number in \[0, 1\], found 5"),
    (dict(stops=[{"mass": 0, "side": "lower", "position": 0.1, "restitution": 0.7}]), "initial state defaults to rest"),
    (dict(record={"events": "yes please"}), "record.events: expected true or false"),
])
def test_the_loader_checks_the_physics_with_its_messages(changes, message, tmp_path):
    with pytest.raises(vibro.SceneError, match=message) as raised:
        paper(**changes)
    assert isinstance(raised.value, ValueError) and raised.value.file == "<numpy>" and raised.value.line > 0


def test_the_message_is_the_commands_for_the_same_text(tmp_path, cli):
    """A numpy scene's error is the command's for the generated text (file name aside)."""
    with pytest.raises(vibro.SceneError) as raised:
        paper(M=np.array([[1.0, 0.5], [0.0, 1.0]]))
    text = paper().yaml.replace("- [1.0, 0.0]", "- [1.0, 0.5]", 1)
    code, err = cli("check", write(tmp_path, "numpy.yaml", text))
    assert code == 2 and err.strip() == "error: " + str(raised.value).replace("<numpy>", str(tmp_path / "numpy.yaml"))

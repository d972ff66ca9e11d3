"""Every error path of a bad scene raises in Python with the message of the command line
(vibro check / vibro run --set), as vibro.SceneError, a ValueError carrying file, line, column,
path and problem; nothing crashes the interpreter."""
import re

import pytest
import vibro
from conftest import PAPER, SOURCE, write

MALFORMED = sorted((SOURCE / "tests/io/malformed").glob("*.yaml"))


def cli_message(cli, *args):
    code, err = cli(*args)
    assert code == 2, err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    return err[len("error: "):-1]


def test_there_are_malformed_scenes():
    assert len(MALFORMED) > 80


@pytest.mark.parametrize("scene", MALFORMED, ids=lambda p: p.stem)
def test_malformed_scene_raises_the_commands_message(scene, cli):
    expected = cli_message(cli, "check", scene)
    with pytest.raises(ValueError) as raised:
        vibro.Scene.load(scene)
    error = raised.value
    if isinstance(error, vibro.SceneError):
        assert str(error) == expected
        position = f"{error.file}:{error.line}:{error.column}: " if error.line > 0 else f"{error.file}: "
        assert str(error).startswith(position + (error.path + ": " if error.path else ""))
        assert str(error).endswith(error.problem)
    else:  # the command prefixes errors of the engine's validation with the scene file
        assert f"{scene}: {error}" == expected


def test_malformed_text_names_its_file(cli, tmp_path):
    text = (SOURCE / "tests/io/malformed/stop_misspelled_key.yaml").read_text()
    scene = write(tmp_path, "bad.yaml", text)
    expected = cli_message(cli, "check", scene)
    with pytest.raises(vibro.SceneError) as raised:
        vibro.Scene.from_text(text, str(scene))
    assert str(raised.value) == expected and "did you mean" in expected


def test_a_missing_file(cli, tmp_path):
    expected = cli_message(cli, "check", tmp_path / "none.yaml")
    with pytest.raises(vibro.SceneError, match=re.escape(expected)):
        vibro.Scene.load(tmp_path / "none.yaml")


@pytest.mark.parametrize("path, value", [
    ("forcing.frequenc", 0.26),             # no such key ("paths name values the file sets")
    ("stops[7].position", 0.1),             # no such element
    ("stops[0].side", 1.0),                 # not a number
    ("forcing.frequency", -1.0),            # out of range, as the loader says
    ("stops[1].position", -0.5),            # makes the scene invalid: the start violates the stop
    ("stops[0].restitution", float("nan")),
    ("forcing.cosine[0", 1.0),              # malformed path
])
def test_set_raises_the_message_of_set(path, value, cli, tmp_path):
    scene_file = write(tmp_path, "scene.yaml", PAPER)
    expected = cli_message(cli, "check", scene_file, "--set", f"{path}={value!r}")
    scene = vibro.Scene.load(scene_file)
    before = scene.yaml, scene.get("forcing.frequency"), scene.get("stops[1].position")
    with pytest.raises(vibro.SceneError) as raised:
        scene.set(path, value)
    assert str(raised.value) == expected
    assert (scene.yaml, scene.get("forcing.frequency"), scene.get("stops[1].position")) == before  # unchanged


def test_a_bad_record_keyword_raises_the_loaders_message():
    scene = vibro.Scene.from_text(PAPER.split("record:")[0].replace("frequency: 0.255", "frequency: 0"))
    with pytest.raises(vibro.SceneError, match="record.statistics: per-period statistics and Poincaré points need"):
        vibro.simulate(scene, statistics=True)
    with pytest.raises(TypeError, match="unknown keyword 'event'"):
        vibro.simulate(scene, event=True)
    with pytest.raises(TypeError, match="samples: expected"):
        vibro.simulate(scene, samples=-1)


def test_a_start_inside_a_stop_is_refused_with_the_loaders_message():
    scene = vibro.Scene.from_text(PAPER)
    scene.update({"initial.x[1]": 0.1, "initial.v[1]": 1.0})
    result = vibro.simulate(scene, periods=1)  # starting on the stop, moving into it: an impact
    assert result.status == "completed"
    with pytest.raises(vibro.SceneError, match="initial.x"):
        scene.set("initial.x[1]", 0.2)  # beyond the stop

"""The module's contract beyond the numbers: observers chosen by record: or keywords (what is not
asked for is not there), results that cannot be changed by accident, save() that does not
overwrite unasked, read() of a file that is not a result, sweeps' per-point rows."""
import numpy as np
import pytest
import vibro
from conftest import PAPER, write

SCENE = PAPER + "run: {transient_periods: 10, periods: 2}\n"
RECORDED = {"events", "contacts", "samples", "poincare", "stats"}


def groups(result):
    return set(result.groups) - {"scene", "meta"}


def test_observers_are_the_scenes_record_or_the_keywords():
    scene = vibro.Scene.from_text(SCENE)
    assert groups(vibro.simulate(scene)) == RECORDED
    assert groups(vibro.simulate(scene, record={"statistics": True})) == {"stats"}
    assert groups(vibro.simulate(scene, events=False, samples=0)) == RECORDED - {"events", "samples"}
    times = vibro.simulate(scene, record={}, sample_times=[0.0, 1.5, 3.0])
    assert groups(times) == {"samples"} and list(times.samples.t - times.samples.t[0]) == [0.0, 1.5, 3.0]
    nothing = vibro.simulate(scene, record={})
    assert groups(nothing) == set() and nothing.meta["impacts"] > 0  # it ran, recording nothing
    assert scene.record["events"] and scene.record["samples_per_period"] == 50  # the scene is unchanged


def test_keywords_override_the_run_for_that_run_only():
    scene = vibro.Scene.from_text(SCENE)
    r = vibro.simulate(scene, periods=3, transient_periods=0)
    assert r.stats.sticking_fraction.shape == (3, 2) and r.scene.attrs["periods"] == 3.0
    assert scene.periods == 2 and scene.transient_periods == 10


def test_results_are_read_only_and_named_as_the_file():
    r = vibro.simulate(vibro.Scene.from_text(SCENE))
    assert r["events/t"] is r.events.t and r.events.t.dtype == np.float64 and r.events.kind.dtype == np.int32
    assert r.scene.stop_name.tolist() == ["s1", "s2"] and r.scene.stop_mass.dtype == np.int64
    with pytest.raises(ValueError):
        r.events.t[0] = 1.0
    with pytest.raises(KeyError, match="/sweep: not in this result"):
        r["sweep"]
    with pytest.raises(AttributeError, match="no such group"):
        r.transitions
    assert "events/t" in r and "t" in r.events and "sweep" not in r


def test_save_writes_whole_files_and_does_not_replace_unasked(tmp_path):
    r = vibro.simulate(vibro.Scene.from_text(SCENE))
    r.save(tmp_path / "out.h5")
    with pytest.raises(vibro.ResultError, match="exists; not replaced"):
        r.save(tmp_path / "out.h5")
    r.save(tmp_path / "out.h5", overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.h5"]  # no partial file left
    assert (tmp_path / "out.h5").read_bytes() == r.to_bytes()
    with pytest.raises(vibro.ResultError):
        r.save(tmp_path / "no such folder" / "out.h5")


def test_read_refuses_what_is_not_a_result(tmp_path):
    with pytest.raises(vibro.ResultError, match="cannot read"):
        vibro.read(tmp_path / "none.h5")
    with pytest.raises(OSError, match="not an HDF5 file image"):
        vibro.read(write(tmp_path, "text.h5", "not HDF5"))
    with pytest.raises(vibro.ResultError, match="not a regular file"):
        vibro.read(tmp_path)


def test_sweep_point_rows():
    scene = vibro.Scene.from_text(SCENE)
    r = vibro.sweep(scene, {"forcing.frequency": [0.255, 0.27]}, threads=2)
    assert r.sweep.values[:, 0].tolist() == [0.255, 0.27]
    for p, omega in enumerate([0.255, 0.27]):
        rows = r.point_rows("events", p)
        assert np.array_equal(rows["t"], r.events.t[r.events.point == p])
        scene.set("forcing.frequency", omega)
        alone = vibro.simulate(scene)
        assert np.array_equal(rows["t"], alone.events.t)  # a sweep point is the simulation of its scene
        assert np.array_equal(r.point_rows("samples", p)["x"], alone.samples.x)


def test_sweep_and_locate_need_their_grid():
    scene = vibro.Scene.from_text(SCENE)
    with pytest.raises(ValueError, match="give parameters"):
        vibro.sweep(scene)
    with pytest.raises(ValueError, match="one or two paths"):
        vibro.sweep(scene, {"a": [1], "b": [2], "c": [3]})
    with pytest.raises(vibro.SceneError, match="does not name a number"):
        vibro.sweep(scene, {"forcing.frequenc": [0.25]})
    with pytest.raises(ValueError, match="give path and values"):
        vibro.locate(scene)
